//! The visibility and attribute passes in compute (`shaders/compute_splat.wgsl`),
//! past the raster hardware's blending rate: splats binned to 8×8-pixel
//! tiles by a counting sort, each tile's splats tested by one thread per
//! pixel in chunks of at most 64 (a dense tile is split over several
//! workgroups), sums in registers added once per work item. The visible
//! depth and the sums stay in two storage buffers, which the shared shade
//! pass reads in place of the raster path's depth and accumulation targets
//! (a full-screen copy into those targets took 1.3 ms at 1080p on an H200,
//! more than the splat passes).
//!
//! The tiles' lists live in one buffer whose size the frame's splats decide.
//! A frame whose lists do not fit is still drawn whole: the splats that did
//! not fit go in a list apart that every tile runs over (slow when many
//! overflow, but nothing is lost), and the renderer reads the total back to
//! size the buffer for the next frame.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, compute_pass, layout, pipeline_layout, shader, storage_entry, texture_entry,
    uniform_entry,
};
use super::targets::Targets;
use crate::error::{RenderError, Result};

/// Tile side in pixels (`TILE` in the shader).
const TILE: u32 = 8;
/// Words before the per-tile arrays in the tiles buffer (`HEAD`).
const HEAD: u64 = 3;
/// Workgroup size of the per-splat passes.
const PER_SPLAT: u32 = 256;
/// Largest workgroup count per dispatch dimension (`ROW`).
const ROW: u32 = 65_535;

/// A read-write storage buffer at `binding`, seen by compute shaders.
fn storage_rw(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: false },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        ..storage_entry(binding, wgpu::ShaderStages::COMPUTE)
    }
}

/// The tiles' list memory and what the last frames needed of it.
struct Entries {
    buffer: wgpu::Buffer,
    capacity: u32,
}

/// Reading a frame's list total back, a frame or more late.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Readback {
    /// Nothing in flight: the next frame copies its total.
    Idle,
    /// A frame copied its total, mapped when its commands are submitted;
    /// the callback sets `mapped`.
    Mapping,
}

/// The compute splat passes, their working memory and pipelines.
pub(super) struct ComputeSplats {
    layout: wgpu::BindGroupLayout,
    dispatch_layout: wgpu::BindGroupLayout,
    clear: wgpu::ComputePipeline,
    bin: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    lone_dispatch: wgpu::ComputePipeline,
    visibility: wgpu::ComputePipeline,
    attributes: wgpu::ComputePipeline,
    lone_visibility: wgpu::ComputePipeline,
    lone_attributes: wgpu::ComputePipeline,
    /// Tiles across and down, entry capacity, splats the buffer holds.
    setup: wgpu::Buffer,
    /// Draw arguments for uploaded splats (the count at word 1).
    own_args: wgpu::Buffer,
    /// The work items' indirect dispatch and the totals.
    dispatch: wgpu::Buffer,
    totals: wgpu::Buffer,
    tiles: wgpu::Buffer,
    depth_bits: wgpu::Buffer,
    accum: wgpu::Buffer,
    rects: wgpu::Buffer,
    size: (u32, u32),
    splat_capacity: u32,
    entries: Mutex<Entries>,
    readback: Mutex<Readback>,
    /// Set by the totals' map callback: 1 mapped, 2 failed.
    mapped: std::sync::Arc<AtomicU32>,
    /// Frames whose lists did not fit (drawn by the all-tiles fallback).
    overflows: AtomicU32,
    /// The most list entries one binding holds on this device.
    entry_limit: u32,
    /// The list entries the last frame read back needed (0 before one).
    needed: AtomicU32,
}

impl ComputeSplats {
    /// The passes for `width`×`height` targets, for up to
    /// `splat_capacity` splats.
    pub(super) fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        splat_capacity: u32,
    ) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let splat_layout = layout(
            device,
            "compute splat layout",
            &[
                uniform_entry(0, c),
                storage_entry(1, c),
                uniform_entry(2, c),
                storage_entry(3, c),
                storage_rw(4),
                storage_rw(5),
                storage_rw(6),
                storage_rw(7),
                storage_rw(8),
                texture_entry(9, c, wgpu::TextureSampleType::Depth),
            ],
        );
        let dispatch_layout = layout(device, "compute splat dispatch layout", &[storage_rw(0)]);
        let module = shader(
            device,
            "compute_splat.wgsl",
            &[
                include_str!("../shaders/frame.wgsl"),
                include_str!("../shaders/disc.wgsl"),
                include_str!("../shaders/compute_splat.wgsl"),
            ],
        );
        let plain = pipeline_layout(device, "compute splat pipeline layout", &[&splat_layout]);
        let with_dispatch = pipeline_layout(
            device,
            "compute splat scan pipeline layout",
            &[&splat_layout, &dispatch_layout],
        );
        let pipeline = |entry: &str, layout: &wgpu::PipelineLayout| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        use wgpu::BufferUsages as U;
        let buffer = |label, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let (tiles, depth_bits, accum) = size_buffers(device, width, height);
        let entry_limit = max_entries(device);
        let capacity = initial_entries(splat_capacity, width, height).min(entry_limit);
        Self {
            clear: pipeline("cs_clear", &plain),
            bin: pipeline("cs_bin", &plain),
            scan: pipeline("cs_scan", &with_dispatch),
            scatter: pipeline("cs_scatter", &plain),
            lone_dispatch: pipeline("cs_lone_dispatch", &with_dispatch),
            visibility: pipeline("cs_visibility", &plain),
            attributes: pipeline("cs_attributes", &plain),
            lone_visibility: pipeline("cs_lone_visibility", &plain),
            lone_attributes: pipeline("cs_lone_attributes", &plain),
            layout: splat_layout,
            dispatch_layout,
            setup: buffer("compute splat setup", 16, U::UNIFORM | U::COPY_DST),
            own_args: buffer("compute splat count", 16, U::STORAGE | U::COPY_DST),
            dispatch: buffer(
                "compute splat dispatch",
                48,
                U::STORAGE | U::INDIRECT | U::COPY_SRC,
            ),
            totals: buffer("compute splat totals", 8, U::COPY_DST | U::MAP_READ),
            tiles,
            depth_bits,
            accum,
            rects: rects_buffer(device, splat_capacity),
            size: (width, height),
            splat_capacity,
            entries: Mutex::new(Entries {
                buffer: entries_buffer(device, capacity),
                capacity,
            }),
            readback: Mutex::new(Readback::Idle),
            mapped: Default::default(),
            overflows: AtomicU32::new(0),
            entry_limit,
            needed: AtomicU32::new(0),
        }
    }

    /// Sizes the working memory for `width`×`height` targets and up to
    /// `splat_capacity` splats.
    pub(super) fn reserve(
        &mut self,
        device: &wgpu::Device,
        (width, height): (u32, u32),
        splat_capacity: u32,
    ) {
        if (width, height) != self.size {
            (self.tiles, self.depth_bits, self.accum) = size_buffers(device, width, height);
            self.size = (width, height);
        }
        if splat_capacity > self.splat_capacity {
            self.rects = rects_buffer(device, splat_capacity);
            self.splat_capacity = splat_capacity;
        }
        // The lists' first guess for this many splats (the readback grows
        // them further when a frame needs more).
        let entries = self.entries.get_mut().unwrap_or_else(|e| e.into_inner());
        let capacity = initial_entries(self.splat_capacity, width, height).min(self.entry_limit);
        if capacity > entries.capacity {
            entries.buffer = entries_buffer(device, capacity);
            entries.capacity = capacity;
        }
    }

    /// The list entries a frame needed, as last read back, when that is
    /// past what one binding holds on this device (such frames draw the
    /// splats that do not fit through the all-tiles list, slowly).
    /// As bytes needed and bytes held.
    pub(super) fn past_limit(&self) -> Option<(u64, u64)> {
        let needed = self.needed.load(Ordering::Relaxed);
        (needed > self.entry_limit)
            .then(|| (u64::from(needed) * 4, u64::from(self.entry_limit) * 4))
    }

    /// Lowers the entry limit, to test what happens past it.
    #[cfg(test)]
    pub(super) fn limit_entries(&mut self, limit: u32) {
        self.entry_limit = limit;
    }

    /// The visible depth per pixel, row-major: f32 bits, the scene's depth
    /// where no splat is nearer. Read by the shade pass.
    pub(super) fn depth_bits(&self) -> &wgpu::Buffer {
        &self.depth_bits
    }

    /// The attribute sums per pixel, row-major: four f32 bits, Σw·n and Σw.
    /// Read by the shade pass.
    pub(super) fn sums(&self) -> &wgpu::Buffer {
        &self.accum
    }

    /// Frames so far (as read back, a frame or more late) whose tile lists
    /// did not fit their buffer, their overflowing splats drawn from a list
    /// apart.
    pub(super) fn overflows(&self) -> u32 {
        self.overflows.load(Ordering::Relaxed)
    }

    /// Reads an earlier frame's list total once its mapping is done, and
    /// grows the list memory to it.
    fn settle(&self, device: &wgpu::Device) {
        let mut state = self.readback.lock().unwrap_or_else(|e| e.into_inner());
        if *state == Readback::Mapping {
            let _ = device.poll(wgpu::PollType::Poll);
            match self.mapped.swap(0, Ordering::Acquire) {
                1 => {
                    if let Ok(view) = self.totals.get_mapped_range(..) {
                        let words: &[u32] = bytemuck::cast_slice(&view[..8]);
                        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
                        self.needed.store(words[0], Ordering::Relaxed);
                        if words[0] > entries.capacity {
                            self.overflows.fetch_add(1, Ordering::Relaxed);
                            // Past the binding limit the overflow list
                            // draws the rest, every frame.
                            let capacity = (words[0].checked_next_power_of_two())
                                .unwrap_or(u32::MAX)
                                .min(self.entry_limit);
                            if capacity > entries.capacity {
                                entries.buffer = entries_buffer(device, capacity);
                                entries.capacity = capacity;
                            }
                        }
                    }
                    self.totals.unmap();
                    *state = Readback::Idle;
                }
                2 => *state = Readback::Idle,
                _ => {}
            }
        }
    }

    /// Records the compute splat passes over `splats` (counted by
    /// `draw_args`, or `count` uploaded ones when it is `None`) into the
    /// targets `t`, timed by `profiler` where there is one.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn record(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        frame: &wgpu::Buffer,
        splats: &wgpu::Buffer,
        draw_args: Option<&wgpu::Buffer>,
        count: u32,
        t: &Targets,
    ) {
        self.settle(device);
        let (width, height) = (t.width, t.height);
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        queue.write_buffer(
            &self.setup,
            0,
            bytemuck::cast_slice(&[tiles_x, tiles_y, entries.capacity, self.splat_capacity]),
        );
        let args = match draw_args {
            Some(args) => args,
            None => {
                queue.write_buffer(
                    &self.own_args,
                    0,
                    bytemuck::cast_slice(&[4u32, count, 0, 0]),
                );
                &self.own_args
            }
        };
        let group = bind_in_order(
            device,
            "compute splat bind group",
            &self.layout,
            [
                frame.as_entire_binding(),
                splats.as_entire_binding(),
                self.setup.as_entire_binding(),
                args.as_entire_binding(),
                self.rects.as_entire_binding(),
                self.tiles.as_entire_binding(),
                entries.buffer.as_entire_binding(),
                self.depth_bits.as_entire_binding(),
                self.accum.as_entire_binding(),
                wgpu::BindingResource::TextureView(&t.depth_view),
            ],
        );
        let dispatch_group = bind_in_order(
            device,
            "compute splat dispatch group",
            &self.dispatch_layout,
            [self.dispatch.as_entire_binding()],
        );
        drop(entries);
        encoder.clear_buffer(&self.tiles, 0, None);
        let per_splat = self.splat_capacity.div_ceil(PER_SPLAT).max(1);
        let splat_groups = (per_splat.min(ROW), per_splat.div_ceil(ROW));
        compute_pass(encoder, profiler, "bin splats", |pass| {
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(&self.clear);
            pass.dispatch_workgroups(tiles_x, tiles_y, 1);
            pass.set_pipeline(&self.bin);
            pass.dispatch_workgroups(splat_groups.0, splat_groups.1, 1);
            pass.set_pipeline(&self.scan);
            pass.set_bind_group(1, &dispatch_group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&self.scatter);
            pass.dispatch_workgroups(splat_groups.0, splat_groups.1, 1);
            pass.set_pipeline(&self.lone_dispatch);
            pass.dispatch_workgroups(1, 1, 1);
        });
        compute_pass(encoder, profiler, "visibility pass", |pass| {
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(&self.visibility);
            pass.dispatch_workgroups_indirect(&self.dispatch, 0);
            pass.set_pipeline(&self.lone_visibility);
            pass.dispatch_workgroups_indirect(&self.dispatch, 32);
        });
        compute_pass(encoder, profiler, "attribute pass", |pass| {
            pass.set_bind_group(0, &group, &[]);
            pass.set_pipeline(&self.attributes);
            pass.dispatch_workgroups_indirect(&self.dispatch, 0);
            pass.set_pipeline(&self.lone_attributes);
            pass.dispatch_workgroups_indirect(&self.dispatch, 32);
        });
        let mut state = self.readback.lock().unwrap_or_else(|e| e.into_inner());
        if *state == Readback::Idle {
            encoder.copy_buffer_to_buffer(&self.dispatch, 12, &self.totals, 0, 8);
            let mapped = self.mapped.clone();
            encoder.map_buffer_on_submit(&self.totals, wgpu::MapMode::Read, .., move |r| {
                mapped.store(if r.is_ok() { 1 } else { 2 }, Ordering::Release);
            });
            *state = Readback::Mapping;
        }
    }
}

/// The largest storage binding this device takes (bytes).
fn binding_limit(device: &wgpu::Device) -> u64 {
    let limits = device.limits();
    limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size)
}

/// Checks that the compute path's memory for `width`×`height` and
/// `splats` fits this device's storage bindings.
///
/// # Errors
/// [`RenderError::ComputeLimit`] naming the buffer.
pub(super) fn check_fits(
    device: &wgpu::Device,
    (width, height): (u32, u32),
    splats: u32,
) -> Result<()> {
    let max = binding_limit(device);
    let sums = u64::from(width) * u64::from(height) * 16;
    let rects = u64::from(splats.max(1)) * 32;
    for (what, bytes) in [("pixel sums", sums), ("splat rectangles", rects)] {
        if bytes > max {
            return Err(RenderError::ComputeLimit { what, bytes, max });
        }
    }
    Ok(())
}

/// Entries to start with: eight tiles per splat, at least four per tile.
fn initial_entries(splats: u32, width: u32, height: u32) -> u32 {
    let tiles = width.div_ceil(TILE) * height.div_ceil(TILE);
    splats.saturating_mul(8).max(4 * tiles).max(1024)
}

/// The most list entries one storage binding holds.
fn max_entries(device: &wgpu::Device) -> u32 {
    u32::try_from(binding_limit(device) / 4).unwrap_or(u32::MAX)
}

fn entries_buffer(device: &wgpu::Device, capacity: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("compute splat entries"),
        size: u64::from(capacity) * 4,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

/// Each splat's pixels, then room for the list of those that overflow.
fn rects_buffer(device: &wgpu::Device, splats: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("compute splat rects"),
        size: u64::from(splats.max(1)) * 32,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

/// The tiles, visibility depth and sums of `width`×`height` targets.
fn size_buffers(
    device: &wgpu::Device,
    width: u32,
    height: u32,
) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
    let tiles = u64::from(width.div_ceil(TILE) * height.div_ceil(TILE));
    let pixels = u64::from(width) * u64::from(height);
    let buffer = |label, size: u64, usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    use wgpu::BufferUsages as U;
    (
        buffer(
            "compute splat tiles",
            (HEAD + 4 * tiles + 2) * 4,
            U::STORAGE | U::COPY_DST,
        ),
        buffer("compute splat depth", pixels * 4, U::STORAGE | U::COPY_SRC),
        buffer("compute splat sums", pixels * 16, U::STORAGE | U::COPY_SRC),
    )
}
