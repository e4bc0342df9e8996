//! XYZ: particle positions as binary f32 triples in the machine's byte
//! order, no header, no attributes, no time: what splashsurf reads (its
//! reader, with the `readers` feature, reads these back).

use glam::Vec3;

/// Appends each position as three f32 in the machine's byte order.
pub(super) fn write_xyz(bytes: &mut Vec<u8>, positions: &[Vec3]) {
    bytes.reserve(12 * positions.len());
    for p in positions {
        for c in p.to_array() {
            bytes.extend_from_slice(&c.to_ne_bytes());
        }
    }
}
