//! The scene pass (`shaders/scene.wgsl`): the backdrop (a full-screen
//! triangle behind everything: the screen-space background or the
//! environment along each view ray), then the [`SceneGeometry`]'s meshes
//! lit by the environment and the sun, into the scene image and the depth
//! buffer the splat passes draw over.

use wgpu_profiler::GpuProfiler;

use super::plumbing::{
    bind_in_order, cleared, depth_attachment, layout, pipeline_layout, render_pass, sampler_entry,
    shader, texture_entry, uniform_entry,
};
use super::targets::{DEPTH_FORMAT, SCENE_FORMAT, Surroundings, Targets};
use crate::error::Result;
use crate::geometry::{Backdrop, GpuVertex, SceneGeometry};

/// The scene geometry's GPU buffers.
struct MeshBuffers {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
}

/// The scene pass: its pipelines, bind group and the geometry it draws.
pub(super) struct ScenePass {
    layout: wgpu::BindGroupLayout,
    group: wgpu::BindGroup,
    backdrop: wgpu::RenderPipeline,
    mesh: wgpu::RenderPipeline,
    geometry: Option<MeshBuffers>,
    /// What fills the pixels the geometry leaves.
    pub(super) backdrop_kind: Backdrop,
    /// Unit direction towards the sun.
    pub(super) sun: glam::Vec3,
}

impl ScenePass {
    /// The pass with no geometry before the screen-space background.
    pub(super) fn new(device: &wgpu::Device, frame: &wgpu::Buffer, around: &Surroundings) -> Self {
        let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let filterable = wgpu::TextureSampleType::Float { filterable: true };
        let layout = layout(
            device,
            "scene layout",
            &[
                uniform_entry(0, stages),
                texture_entry(1, stages, filterable),
                sampler_entry(2, stages),
                texture_entry(3, stages, filterable),
                sampler_entry(4, stages),
            ],
        );
        let module = shader(
            device,
            "scene.wgsl",
            &[
                include_str!("../shaders/frame.wgsl"),
                include_str!("../shaders/scene.wgsl"),
            ],
        );
        let pipeline_layout = pipeline_layout(device, "scene pipeline layout", &[&layout]);
        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4],
        };
        let pipeline =
            |label, vs, fs, buffers: &[Option<wgpu::VertexBufferLayout<'_>>], mesh: bool| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(vs),
                        compilation_options: Default::default(),
                        buffers,
                    },
                    primitive: wgpu::PrimitiveState {
                        cull_mode: mesh.then_some(wgpu::Face::Back),
                        ..Default::default()
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_FORMAT,
                        depth_write_enabled: Some(mesh),
                        depth_compare: Some(if mesh {
                            wgpu::CompareFunction::Less
                        } else {
                            wgpu::CompareFunction::Always
                        }),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(fs),
                        compilation_options: Default::default(),
                        targets: &[Some(SCENE_FORMAT.into())],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
        let backdrop = pipeline("backdrop", "vs_backdrop", "fs_backdrop", &[], false);
        let mesh = pipeline(
            "scene meshes",
            "vs_mesh",
            "fs_mesh",
            &[Some(vertex_layout)],
            true,
        );
        let group = bind(device, &layout, frame, around);
        Self {
            layout,
            group,
            backdrop,
            mesh,
            geometry: None,
            backdrop_kind: Backdrop::Screen,
            sun: crate::geometry::SUN,
        }
    }

    /// Binds new surroundings.
    pub(super) fn rebind(
        &mut self,
        device: &wgpu::Device,
        frame: &wgpu::Buffer,
        around: &Surroundings,
    ) {
        self.group = bind(device, &self.layout, frame, around);
    }

    /// Replaces the geometry (validated and flattened first: nothing
    /// changes on an error).
    ///
    /// # Errors
    /// As [`SceneGeometry::flatten`].
    pub(super) fn set_geometry(
        &mut self,
        device: &wgpu::Device,
        geometry: &SceneGeometry,
    ) -> Result<()> {
        use wgpu::util::DeviceExt;
        let (vertices, indices) = geometry.flatten()?;
        self.geometry = (!indices.is_empty()).then(|| {
            let buffer = |label, contents: &[u8], usage| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
            };
            MeshBuffers {
                vertices: buffer(
                    "scene vertices",
                    bytemuck::cast_slice(&vertices),
                    wgpu::BufferUsages::VERTEX,
                ),
                indices: buffer(
                    "scene indices",
                    bytemuck::cast_slice(&indices),
                    wgpu::BufferUsages::INDEX,
                ),
                count: indices.len() as u32,
            }
        });
        self.backdrop_kind = geometry.backdrop;
        self.sun = geometry.sun.normalize();
        Ok(())
    }

    /// Records the pass: the scene image and depth cleared, the backdrop,
    /// then the meshes.
    pub(super) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        profiler: Option<&GpuProfiler>,
        t: &Targets,
    ) {
        render_pass(
            encoder,
            profiler,
            "scene pass",
            &[cleared(&t.scene_view, wgpu::Color::BLACK)],
            Some(depth_attachment(&t.depth_view, wgpu::LoadOp::Clear(1.0))),
            |pass| {
                pass.set_bind_group(0, &self.group, &[]);
                pass.set_pipeline(&self.backdrop);
                pass.draw(0..3, 0..1);
                if let Some(g) = &self.geometry {
                    pass.set_pipeline(&self.mesh);
                    pass.set_vertex_buffer(0, g.vertices.slice(..));
                    pass.set_index_buffer(g.indices.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..g.count, 0, 0..1);
                }
            },
        );
    }
}

fn bind(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    around: &Surroundings,
) -> wgpu::BindGroup {
    use wgpu::BindingResource::{Sampler, TextureView};
    bind_in_order(
        device,
        "scene bind group",
        layout,
        [
            frame.as_entire_binding(),
            TextureView(&around.environment),
            Sampler(&around.env_sampler),
            TextureView(&around.background),
            Sampler(&around.back_sampler),
        ],
    )
}
