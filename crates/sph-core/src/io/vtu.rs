//! VTU: VTK's XML unstructured grid, the particles as vertex cells,
//! written by `vtkio` (base64 inline binary, which `vtkio` and ParaView
//! read; `vtkio` does not read the raw appended VTU some tools write).
//! Positions only. Needs the `readers` feature.

use glam::Vec3;

/// Appends the VTU file of `positions`.
#[cfg(feature = "readers")]
pub(super) fn write_vtu(bytes: &mut Vec<u8>, positions: &[Vec3]) -> Result<(), String> {
    use splashsurf_lib::vtkio::model::{
        Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version,
        VertexNumbers, Vtk,
    };
    let n = positions.len();
    let flat: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
    let piece = UnstructuredGridPiece {
        points: flat.into(),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: (0..n as u64).collect(),
                offsets: (1..=n as u64).collect(),
            },
            types: vec![CellType::Vertex; n],
        },
        data: Attributes::new(),
    };
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        title: "particles".into(),
        byte_order: ByteOrder::LittleEndian,
        data: DataSet::inline(piece),
        file_path: None,
    };
    vtk.write_xml(bytes).map_err(|e| e.to_string())
}

#[cfg(not(feature = "readers"))]
pub(super) fn write_vtu(_: &mut Vec<u8>, _: &[Vec3]) -> Result<(), String> {
    Err(".vtu files need sph-core's `readers` feature".into())
}
