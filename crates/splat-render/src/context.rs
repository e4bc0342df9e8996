//! [`GpuContext`]: one owner of the wgpu instance, adapter, device and queue.

use std::sync::{Arc, Mutex};

use crate::error::{RenderError, Result};

/// The device and queue every renderer object is created on, for a window surface
/// or headless.
///
/// Adapter choice honours wgpu's environment variables: `WGPU_BACKEND` (e.g.
/// `vulkan`, `gl`) restricts the backends, `WGPU_ADAPTER_NAME` picks the first
/// adapter whose name contains the (case-insensitive) value, `WGPU_POWER_PREF`
/// (`low`/`high`) steers the default choice.
#[derive(Debug)]
pub struct GpuContext {
    /// The wgpu instance (needed to create window surfaces).
    pub instance: wgpu::Instance,
    /// The chosen adapter.
    pub adapter: wgpu::Adapter,
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The first error the device reported on its own (an uncaptured
    /// validation or out-of-memory error, or the device lost), for
    /// [`GpuContext::check`].
    fault: Arc<Mutex<Option<String>>>,
}

impl GpuContext {
    /// A context without a window: render into textures and read them back.
    ///
    /// # Errors
    /// [`RenderError::NoAdapter`] when no adapter exists (with the hint to install
    /// a software Vulkan driver), [`RenderError::AdapterNotFound`] when
    /// `WGPU_ADAPTER_NAME` matches none, [`RenderError::RequestDevice`] when the
    /// adapter refuses a device.
    pub fn headless() -> Result<Self> {
        let instance = instance_from_env();
        pollster::block_on(Self::with_instance(instance, None))
    }

    /// A context whose adapter can present to `surface`, which must have been
    /// created from `instance` (see [`instance_from_env`]).
    ///
    /// # Errors
    /// As [`GpuContext::headless`].
    pub async fn for_surface(
        instance: wgpu::Instance,
        surface: &wgpu::Surface<'_>,
    ) -> Result<Self> {
        Self::with_instance(instance, Some(surface)).await
    }

    async fn with_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Self> {
        let adapter = choose_adapter(&instance, surface).await?;
        let info = adapter.get_info();
        log::info!(
            "GPU adapter: {} ({:?}, {:?})",
            info.name,
            info.device_type,
            info.backend
        );
        // Float32 blending lets the attribute pass accumulate in full precision;
        // without it the renderer falls back to Rgba16Float.
        // Timestamps for the passes' profiles (`wgpu_profiler`), where offered.
        let wanted = wgpu::Features::FLOAT32_BLENDABLE | wgpu::Features::TIMESTAMP_QUERY;
        let required_features = adapter.features() & wanted;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("splat-render device"),
                required_features,
                required_limits: adapter.limits(),
                ..Default::default()
            })
            .await
            .map_err(|source| RenderError::RequestDevice {
                adapter: info.name.clone(),
                source,
            })?;
        // wgpu's default handler panics on an error no call returns; here
        // the first is kept for `check`, every one logged.
        let fault = Arc::new(Mutex::new(None));
        let keep = |fault: &Arc<Mutex<Option<String>>>, message: String| {
            if let Ok(mut f) = fault.lock() {
                f.get_or_insert(message);
            }
        };
        let kept = Arc::clone(&fault);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let line = e
                .to_string()
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ");
            log::error!("GPU device: {line}");
            keep(&kept, line);
        }));
        let kept = Arc::clone(&fault);
        device.set_device_lost_callback(move |reason, message| {
            // Destroyed: by `destroy` or as the device is dropped at exit,
            // which is no news; any other reason is.
            if reason != wgpu::DeviceLostReason::Destroyed {
                log::error!("GPU device lost ({reason:?}): {message}");
            }
            let why = if message.trim().is_empty() {
                String::new()
            } else {
                format!(": {}", message.trim())
            };
            keep(&kept, format!("the device was lost ({reason:?}){why}"));
        });
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            fault,
        })
    }

    /// The first error the device reported outside any call that returns
    /// one since it was created: an uncaptured validation or out-of-memory
    /// error (wgpu's default would panic), or the device lost. Frames call
    /// it once each, so that such an error ends the run with a message.
    ///
    /// # Errors
    /// [`RenderError::Device`] with the device's message.
    pub fn check(&self) -> Result<()> {
        match self.fault.lock().ok().and_then(|f| f.clone()) {
            Some(message) => Err(RenderError::Device(message)),
            None => Ok(()),
        }
    }

    /// For GPU tests: one headless context for the whole process (the tests
    /// of a binary run on threads and share it; a device per test starts
    /// slowly on lavapipe), or `None` after printing `skipped: no GPU adapter
    /// (…)` once when there is no adapter.
    ///
    /// # Panics
    /// When there is no adapter and `SPH_REQUIRE_GPU=1` (as CI sets it), so a
    /// machine that should have a (software) GPU cannot skip silently.
    pub fn headless_or_skip() -> Option<&'static Self> {
        static SHARED: std::sync::OnceLock<Option<GpuContext>> = std::sync::OnceLock::new();
        SHARED
            .get_or_init(|| match Self::headless() {
                Ok(ctx) => Some(ctx),
                Err(err) if std::env::var("SPH_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
                    panic!("SPH_REQUIRE_GPU=1 but: {err}")
                }
                Err(err) => {
                    eprintln!("skipped: no GPU adapter ({err})");
                    None
                }
            })
            .as_ref()
    }

    /// The adapter's name and backend, for logs and reports.
    pub fn adapter_summary(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend)
    }

    /// Whether the adapter is a CPU rasteriser (lavapipe, llvmpipe, WARP).
    pub fn is_software(&self) -> bool {
        self.adapter.get_info().device_type == wgpu::DeviceType::Cpu
    }
}

/// A wgpu instance configured from the environment (`WGPU_BACKEND`, `WGPU_DEBUG`, …).
pub fn instance_from_env() -> wgpu::Instance {
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

async fn choose_adapter(
    instance: &wgpu::Instance,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<wgpu::Adapter> {
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all());
    // GL adapters cannot run the splat passes (no `textureLoad` from depth
    // textures): never chosen, and named in the error where they are all
    // there is.
    let compatible = |a: &wgpu::Adapter| {
        surface.is_none_or(|s| a.is_surface_supported(s))
            && a.get_info().backend != wgpu::Backend::Gl
    };
    let gl_only = |adapters: &[wgpu::Adapter]| {
        (adapters.iter())
            .find(|a| a.get_info().backend == wgpu::Backend::Gl)
            .map(|a| RenderError::GlBackend {
                adapter: a.get_info().name,
            })
    };
    if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME") {
        let wanted = wanted.to_lowercase();
        let adapters = instance.enumerate_adapters(backends).await;
        let available: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        let named = |a: &&wgpu::Adapter| a.get_info().name.to_lowercase().contains(&wanted);
        if let Some(a) = adapters.iter().filter(named).find(|a| compatible(a)) {
            return Ok(a.clone());
        }
        let named: Vec<wgpu::Adapter> = adapters.iter().filter(named).cloned().collect();
        return Err(gl_only(&named).unwrap_or(RenderError::AdapterNotFound { wanted, available }));
    }
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::from_env().unwrap_or_default(),
        force_fallback_adapter: false,
        compatible_surface: surface,
        apply_limit_buckets: false,
    };
    let err = match instance.request_adapter(&options).await {
        Ok(adapter) if compatible(&adapter) => return Ok(adapter),
        Ok(adapter) => format!("{} is on GL", adapter.get_info().name),
        Err(err) => err.to_string(),
    };
    // request_adapter may skip CPU adapters on some backends, or offer a GL
    // one; take any compatible adapter before giving up.
    let adapters = instance.enumerate_adapters(backends).await;
    if let Some(a) = adapters.iter().find(|a| compatible(a)) {
        return Ok(a.clone());
    }
    Err(
        gl_only(&adapters).unwrap_or_else(|| RenderError::NoAdapter {
            detail: format!(" (backends {backends:?}: {err})"),
        }),
    )
}
