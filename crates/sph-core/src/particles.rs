//! The particle container: struct-of-arrays storage of the fields every SPH solver
//! needs, plus named extra attributes that user processors add and read (the
//! thesis's extensible particle container, section 4.3.1).
//!
//! All arrays always have the same length. Adding, removing and reordering
//! particles goes through [`Particles`] so that built-in fields and extra
//! attributes stay in step; slices handed out can change values, never lengths.

use std::any::Any;
use std::collections::BTreeMap;

use glam::Vec3;
use std::ops::Range;

use crate::error::{Error, Result};
use crate::region::Blocks;

/// Names of the built-in fields; extra attributes may not reuse them.
pub const BUILTIN_FIELDS: [&str; 9] = [
    "id",
    "position",
    "velocity",
    "acceleration",
    "density",
    "pressure",
    "mass",
    "colour_gradient",
    "colour_laplacian",
];

/// Struct-of-arrays particle storage.
///
/// ```
/// use sph_core::{Particles, glam::Vec3};
/// let mut p = Particles::new();
/// p.push(Vec3::ZERO, Vec3::X, 0.5);
/// p.add_attribute("temperature", 293.0f32).unwrap();
/// p.attribute_mut::<f32>("temperature").unwrap()[0] += 10.0;
/// assert_eq!(p.attribute::<f32>("temperature").unwrap(), &[303.0]);
/// ```
#[derive(Default)]
pub struct Particles {
    ids: Vec<u64>,
    next_id: u64,
    positions: Vec<Vec3>,
    velocities: Vec<Vec3>,
    accelerations: Vec<Vec3>,
    densities: Vec<f32>,
    pressures: Vec<f32>,
    masses: Vec<f32>,
    colour_gradients: Vec<Vec3>,
    colour_laplacians: Vec<f32>,
    extra: BTreeMap<String, Box<dyn Column>>,
    /// The memory of the last permutation's old columns, which the next one
    /// fills (fresh columns every substep cost page faults).
    spare: Spare,
}

/// Spare columns for [`Particles::permute`]: one per built-in column where
/// a step's team gathers every column at once, else the first of each type.
#[derive(Default)]
struct Spare {
    ids: Vec<u64>,
    vec3s: [Vec<Vec3>; 4],
    f32s: [Vec<f32>; 4],
}

/// Mutable views of every built-in field at once, for processors that read some
/// fields while writing others.
pub struct FieldsMut<'a> {
    /// Stable particle identifiers (read-only: ids never change).
    pub ids: &'a [u64],
    /// Positions x (m).
    pub positions: &'a mut [Vec3],
    /// Velocities v (m/s).
    pub velocities: &'a mut [Vec3],
    /// Accelerations a (m/s²), the sum of forces divided by mass.
    pub accelerations: &'a mut [Vec3],
    /// Densities ρ (kg/m³).
    pub densities: &'a mut [f32],
    /// Pressures p (Pa).
    pub pressures: &'a mut [f32],
    /// Masses m (kg).
    pub masses: &'a mut [f32],
    /// Colour-field gradients n = ∇c (1/m), eq. 19.
    pub colour_gradients: &'a mut [Vec3],
    /// Colour-field laplacians ∇²c (1/m²), eq. 20.
    pub colour_laplacians: &'a mut [f32],
}

macro_rules! field_accessors {
    ($($(#[$doc:meta])* $name:ident, $name_mut:ident: $ty:ty;)*) => {$(
        $(#[$doc])*
        #[inline]
        pub fn $name(&self) -> &[$ty] {
            &self.$name
        }
        $(#[$doc])*
        ///
        /// Mutable: values may change, the length may not.
        #[inline]
        pub fn $name_mut(&mut self) -> &mut [$ty] {
            &mut self.$name
        }
    )*};
}

impl Particles {
    /// An empty container.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of particles.
    #[inline]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no particles.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Adds a particle at rest state (zero acceleration, density and pressure; extra
    /// attributes at their defaults) and returns its stable id.
    pub fn push(&mut self, position: Vec3, velocity: Vec3, mass: f32) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        self.ids.push(id);
        self.positions.push(position);
        self.velocities.push(velocity);
        self.accelerations.push(Vec3::ZERO);
        self.densities.push(0.0);
        self.pressures.push(0.0);
        self.masses.push(mass);
        self.colour_gradients.push(Vec3::ZERO);
        self.colour_laplacians.push(0.0);
        for column in self.extra.values_mut() {
            column.push_default();
        }
        id
    }

    /// Stable particle identifiers, unique within this container; they follow the
    /// particle through [`Particles::permute`] and [`Particles::retain`].
    #[inline]
    pub fn ids(&self) -> &[u64] {
        &self.ids
    }

    field_accessors! {
        /// Positions x (m).
        positions, positions_mut: Vec3;
        /// Velocities v (m/s).
        velocities, velocities_mut: Vec3;
        /// Accelerations a (m/s²).
        accelerations, accelerations_mut: Vec3;
        /// Densities ρ (kg/m³).
        densities, densities_mut: f32;
        /// Pressures p (Pa): the equation of state's (WCSPH), the density
        /// solve's (DFSPH), or the one the constraint solve applied (PBF).
        pressures, pressures_mut: f32;
        /// Masses m (kg).
        masses, masses_mut: f32;
        /// Colour-field gradients n = ∇c (1/m), eq. 19.
        colour_gradients, colour_gradients_mut: Vec3;
        /// Colour-field laplacians ∇²c (1/m²), eq. 20.
        colour_laplacians, colour_laplacians_mut: f32;
    }

    /// Every built-in field at once, for disjoint mutable borrows.
    pub fn fields_mut(&mut self) -> FieldsMut<'_> {
        FieldsMut {
            ids: &self.ids,
            positions: &mut self.positions,
            velocities: &mut self.velocities,
            accelerations: &mut self.accelerations,
            densities: &mut self.densities,
            pressures: &mut self.pressures,
            masses: &mut self.masses,
            colour_gradients: &mut self.colour_gradients,
            colour_laplacians: &mut self.colour_laplacians,
        }
    }

    /// Adds a named per-particle attribute of element type `T`, every particle
    /// (present and future) starting at `default`.
    ///
    /// Errors if the name is taken, by a built-in field or another attribute.
    pub fn add_attribute<T>(&mut self, name: &str, default: T) -> Result<()>
    where
        T: Clone + Send + Sync + 'static,
    {
        if BUILTIN_FIELDS.contains(&name) || self.extra.contains_key(name) {
            return Err(Error::DuplicateAttribute(name.to_owned()));
        }
        let column = TypedColumn {
            data: vec![default.clone(); self.len()],
            default,
        };
        self.extra.insert(name.to_owned(), Box::new(column));
        Ok(())
    }

    /// Removes a named attribute; errors if it does not exist.
    pub fn remove_attribute(&mut self, name: &str) -> Result<()> {
        self.extra
            .remove(name)
            .map(drop)
            .ok_or_else(|| Error::MissingAttribute(name.to_owned()))
    }

    /// Whether an extra attribute of this name exists.
    pub fn has_attribute(&self, name: &str) -> bool {
        self.extra.contains_key(name)
    }

    /// Names of the extra attributes, in sorted order.
    pub fn attribute_names(&self) -> impl Iterator<Item = &str> {
        self.extra.keys().map(String::as_str)
    }

    /// The values of a named attribute; errors if it is missing or holds another type.
    pub fn attribute<T: 'static>(&self, name: &str) -> Result<&[T]> {
        let column = self
            .extra
            .get(name)
            .ok_or_else(|| Error::MissingAttribute(name.to_owned()))?;
        let type_name = column.type_name();
        column
            .as_any()
            .downcast_ref::<TypedColumn<T>>()
            .map(|c| c.data.as_slice())
            .ok_or_else(|| Error::AttributeType {
                name: name.to_owned(),
                actual: type_name,
                requested: std::any::type_name::<T>(),
            })
    }

    /// The values of a named attribute, mutable (values, not length).
    pub fn attribute_mut<T: 'static>(&mut self, name: &str) -> Result<&mut [T]> {
        let column = self
            .extra
            .get_mut(name)
            .ok_or_else(|| Error::MissingAttribute(name.to_owned()))?;
        let type_name = column.type_name();
        column
            .as_any_mut()
            .downcast_mut::<TypedColumn<T>>()
            .map(|c| c.data.as_mut_slice())
            .ok_or_else(|| Error::AttributeType {
                name: name.to_owned(),
                actual: type_name,
                requested: std::any::type_name::<T>(),
            })
    }

    /// Keeps the particles whose entry in `keep` is true, in their order, removing
    /// the others from every field and attribute. Returns how many were removed.
    pub fn retain(&mut self, keep: &[bool]) -> Result<usize> {
        check_len("keep mask", keep.len(), self.len())?;
        let before = self.len();
        retain_vec(&mut self.ids, keep);
        retain_vec(&mut self.positions, keep);
        retain_vec(&mut self.velocities, keep);
        retain_vec(&mut self.accelerations, keep);
        retain_vec(&mut self.densities, keep);
        retain_vec(&mut self.pressures, keep);
        retain_vec(&mut self.masses, keep);
        retain_vec(&mut self.colour_gradients, keep);
        retain_vec(&mut self.colour_laplacians, keep);
        for column in self.extra.values_mut() {
            column.retain(keep);
        }
        Ok(before - self.len())
    }

    /// Reorders every field and attribute so that new slot `k` holds the particle
    /// that was at `order[k]` (e.g. [`crate::NeighbourGrid::order`], which makes
    /// neighbour queries cache-friendly). `order` must be a permutation.
    pub fn permute(&mut self, order: &[u32]) -> Result<()> {
        check_len("order", order.len(), self.len())?;
        let mut seen = vec![false; order.len()];
        for &o in order {
            match seen.get_mut(o as usize) {
                Some(s) if !*s => *s = true,
                _ => {
                    return Err(Error::InvalidParameter {
                        name: "order",
                        value: o.to_string(),
                        reason: "not a permutation: an index is out of range or repeated",
                    });
                }
            }
        }
        self.permute_unchecked(order);
        Ok(())
    }

    /// [`Particles::permute`] for an `order` known to be a permutation of
    /// the particles (a grid's slot order): no check. On the thread that
    /// leads a step's team ([`crate::region::team`], not inside
    /// [`crate::region::released`]: below [`crate::light`]'s 32k particles)
    /// the built-in columns are gathered in one region pass, each block of
    /// slots from every column at once and each column into a spare of its
    /// own, so the team's threads share the work instead of waiting for the
    /// leading one. Elsewhere each column is gathered in turn through one
    /// spare of its type, as [`crate::light`] says.
    pub(crate) fn permute_unchecked(&mut self, order: &[u32]) {
        let n = order.len();
        let Spare { ids, vec3s, f32s } = &mut self.spare;
        let vec3_columns = [
            &mut self.positions,
            &mut self.velocities,
            &mut self.accelerations,
            &mut self.colour_gradients,
        ];
        let f32_columns = [
            &mut self.densities,
            &mut self.pressures,
            &mut self.masses,
            &mut self.colour_laplacians,
        ];
        if crate::region::leading() {
            // A spare holds the old column of the last reordering: refilled,
            // not initialised again, once its length is n.
            ids.resize(n, 0);
            vec3s.iter_mut().for_each(|v| v.resize(n, Vec3::ZERO));
            f32s.iter_mut().for_each(|v| v.resize(n, 0.0));
            {
                let ids_out = Blocks::new(ids);
                let vec3_out = vec3s.each_mut().map(|v| Blocks::new(v));
                let f32_out = f32s.each_mut().map(|v| Blocks::new(v));
                let (ids_in, vec3_in, f32_in) = (&self.ids, &vec3_columns, &f32_columns);
                let gather = |range: Range<usize>, _: usize| {
                    let order = &order[range.clone()];
                    // SAFETY: each block writes its own slots of each spare,
                    // alone; the columns read are not written in the region.
                    unsafe {
                        gather_into(ids_in, order, ids_out.block(range.clone()));
                        for (from, to) in vec3_in.iter().zip(&vec3_out) {
                            gather_into(from, order, to.block(range.clone()));
                        }
                        for (from, to) in f32_in.iter().zip(&f32_out) {
                            gather_into(from, order, to.block(range.clone()));
                        }
                    }
                };
                crate::region::run(n, &[&gather]);
            }
            std::mem::swap(&mut self.ids, ids);
            for (column, spare) in vec3_columns.into_iter().zip(vec3s) {
                std::mem::swap(column, spare);
            }
            for (column, spare) in f32_columns.into_iter().zip(f32s) {
                std::mem::swap(column, spare);
            }
        } else {
            // One spare per type, passed from column to column: large
            // scenes, which reorder here, keep no more spares than that.
            permute_vec(&mut self.ids, order, ids);
            for column in vec3_columns {
                permute_vec(column, order, &mut vec3s[0]);
            }
            for column in f32_columns {
                permute_vec(column, order, &mut f32s[0]);
            }
        }
        for column in self.extra.values_mut() {
            column.permute(order);
        }
    }

    /// Checks what a simulation needs of every particle: a finite position,
    /// a finite velocity and a finite mass above zero (a zero mass would give
    /// its neighbourhood a zero density and the forces NaN). The error names
    /// the first offending particle.
    pub fn validate(&self) -> Result<()> {
        let columns = self
            .positions
            .iter()
            .zip(&self.velocities)
            .zip(&self.masses);
        for (index, ((x, v), &m)) in columns.enumerate() {
            if !x.is_finite() {
                return Err(Error::NonFinitePosition {
                    index,
                    position: x.to_array(),
                });
            }
            if !v.is_finite() {
                return Err(Error::InvalidParticle {
                    index,
                    what: "velocity",
                    value: format!("{v}"),
                    reason: "must be finite",
                });
            }
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::InvalidParticle {
                    index,
                    what: "mass",
                    value: m.to_string(),
                    reason: "must be finite and > 0",
                });
            }
        }
        Ok(())
    }

    /// Total mass Σ m (kg), summed in f64 in index order.
    pub fn total_mass(&self) -> f64 {
        self.masses.iter().map(|&m| m as f64).sum()
    }
}

impl std::fmt::Debug for Particles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Particles")
            .field("len", &self.len())
            .field("attributes", &self.extra.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Clone for Particles {
    fn clone(&self) -> Self {
        Self {
            ids: self.ids.clone(),
            next_id: self.next_id,
            positions: self.positions.clone(),
            velocities: self.velocities.clone(),
            accelerations: self.accelerations.clone(),
            densities: self.densities.clone(),
            pressures: self.pressures.clone(),
            masses: self.masses.clone(),
            colour_gradients: self.colour_gradients.clone(),
            colour_laplacians: self.colour_laplacians.clone(),
            extra: self
                .extra
                .iter()
                .map(|(k, v)| (k.clone(), v.clone_box()))
                .collect(),
            spare: Spare::default(),
        }
    }
}

fn check_len(what: &'static str, actual: usize, expected: usize) -> Result<()> {
    if actual == expected {
        Ok(())
    } else {
        Err(Error::LengthMismatch {
            what,
            actual,
            expected,
        })
    }
}

fn retain_vec<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut k = keep.iter();
    v.retain(|_| *k.next().unwrap_or(&false));
}

/// `to[k] = from[order[k]]` for each slot k of a block.
fn gather_into<T: Copy>(from: &[T], order: &[u32], to: &mut [T]) {
    for (t, &o) in to.iter_mut().zip(order) {
        *t = from[o as usize];
    }
}

/// `v` reordered by `order`, written into `spare`'s memory; `spare` gets
/// the old column's.
fn permute_vec<T: Clone + Send + Sync>(v: &mut Vec<T>, order: &[u32], spare: &mut Vec<T>) {
    use rayon::prelude::*;
    (order
        .par_iter()
        .with_min_len(crate::light::min_piece(order.len())))
    .map(|&o| v[o as usize].clone())
    .collect_into_vec(spare);
    std::mem::swap(v, spare);
}

/// A type-erased attribute column.
trait Column: Send + Sync {
    fn push_default(&mut self);
    fn retain(&mut self, keep: &[bool]);
    fn permute(&mut self, order: &[u32]);
    fn type_name(&self) -> &'static str;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
    fn clone_box(&self) -> Box<dyn Column>;
}

struct TypedColumn<T> {
    data: Vec<T>,
    default: T,
}

impl<T: Clone + Send + Sync + 'static> Column for TypedColumn<T> {
    fn push_default(&mut self) {
        self.data.push(self.default.clone());
    }
    fn retain(&mut self, keep: &[bool]) {
        retain_vec(&mut self.data, keep);
    }
    fn permute(&mut self, order: &[u32]) {
        permute_vec(&mut self.data, order, &mut Vec::new());
    }
    fn type_name(&self) -> &'static str {
        std::any::type_name::<T>()
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
    fn clone_box(&self) -> Box<dyn Column> {
        Box::new(TypedColumn {
            data: self.data.clone(),
            default: self.default.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn three() -> Particles {
        let mut p = Particles::new();
        for i in 0..3 {
            p.push(Vec3::splat(i as f32), Vec3::ZERO, 1.0 + i as f32);
        }
        p
    }

    #[test]
    fn attributes_follow_pushes_removals_and_permutations() {
        let mut p = three();
        p.add_attribute("tag", 7u32).unwrap();
        p.attribute_mut::<u32>("tag").unwrap()[2] = 42;
        p.push(Vec3::ONE, Vec3::ZERO, 9.0);
        assert_eq!(p.attribute::<u32>("tag").unwrap(), &[7, 7, 42, 7]);

        assert_eq!(p.retain(&[true, false, true, true]).unwrap(), 1);
        assert_eq!(p.ids(), &[0, 2, 3]);
        assert_eq!(p.masses(), &[1.0, 3.0, 9.0]);
        assert_eq!(p.attribute::<u32>("tag").unwrap(), &[7, 42, 7]);

        p.permute(&[2, 0, 1]).unwrap();
        assert_eq!(p.ids(), &[3, 0, 2]);
        assert_eq!(p.masses(), &[9.0, 1.0, 3.0]);
        assert_eq!(p.attribute::<u32>("tag").unwrap(), &[7, 7, 42]);
        assert_eq!(p.total_mass(), 13.0);
        // A fresh particle gets a new id, never a reused one.
        assert_eq!(p.push(Vec3::ZERO, Vec3::ZERO, 1.0), 4);
    }

    #[test]
    fn attribute_errors_are_clear() {
        let mut p = three();
        p.add_attribute("heat", 0.0f32).unwrap();
        assert_eq!(
            p.add_attribute("heat", 1.0f32),
            Err(Error::DuplicateAttribute("heat".into()))
        );
        assert!(p.add_attribute("density", 1.0f32).is_err());
        let e = p.attribute::<Vec3>("heat").unwrap_err();
        assert!(e.to_string().contains("holds `f32`"), "{e}");
        assert_eq!(
            p.attribute::<f32>("nope").unwrap_err(),
            Error::MissingAttribute("nope".into())
        );
        assert!(p.retain(&[true]).is_err());
        assert!(p.permute(&[0, 0, 1]).is_err());
        assert!(p.permute(&[0, 1, 3]).is_err());
        p.remove_attribute("heat").unwrap();
        assert!(!p.has_attribute("heat"));
    }

    /// Reordered in a step's team (one region pass, blocks on several
    /// threads) or outside one, every column ends the same, and again when
    /// the spares are refilled.
    #[test]
    fn a_team_reorders_every_column_as_outside_one() {
        let n = 3_000;
        let mut p = Particles::new();
        for i in 0..n {
            let x = i as f32;
            p.push(Vec3::new(x, -x, 0.5 * x), Vec3::splat(x + 0.25), 1.0 + x);
        }
        let f = p.fields_mut();
        for (i, a) in f.accelerations.iter_mut().enumerate() {
            *a = Vec3::new(0.0, i as f32, 1.0);
        }
        for (i, (d, q)) in f
            .densities
            .iter_mut()
            .zip(f.pressures.iter_mut())
            .enumerate()
        {
            (*d, *q) = (1000.0 + i as f32, -(i as f32));
        }
        for (i, (g, l)) in (f.colour_gradients.iter_mut())
            .zip(f.colour_laplacians.iter_mut())
            .enumerate()
        {
            (*g, *l) = (Vec3::splat(i as f32 * 3.0), i as f32 * 7.0);
        }
        p.add_attribute("tag", 0u32).unwrap();
        for (i, t) in p
            .attribute_mut::<u32>("tag")
            .unwrap()
            .iter_mut()
            .enumerate()
        {
            *t = i as u32;
        }
        // A scrambled order, twice.
        let order: Vec<u32> = (0..n as u32).map(|k| (k * 1_237 + 11) % n as u32).collect();
        let (mut outside, mut inside) = (p.clone(), p);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        for _ in 0..2 {
            outside.permute(&order).unwrap();
            pool.install(|| crate::region::team(|| inside.permute_unchecked(&order)));
            assert_eq!(inside.ids(), outside.ids());
            assert_eq!(inside.positions(), outside.positions());
            assert_eq!(inside.velocities(), outside.velocities());
            assert_eq!(inside.accelerations(), outside.accelerations());
            assert_eq!(inside.densities(), outside.densities());
            assert_eq!(inside.pressures(), outside.pressures());
            assert_eq!(inside.masses(), outside.masses());
            assert_eq!(inside.colour_gradients(), outside.colour_gradients());
            assert_eq!(inside.colour_laplacians(), outside.colour_laplacians());
            assert_eq!(
                inside.attribute::<u32>("tag").unwrap(),
                outside.attribute::<u32>("tag").unwrap()
            );
        }
        assert_eq!(outside.ids()[0], order[order[0] as usize] as u64);
        // Fewer particles: spares longer than the columns are refilled.
        let keep: Vec<bool> = (0..n).map(|i| i % 3 != 0).collect();
        inside.retain(&keep).unwrap();
        outside.retain(&keep).unwrap();
        let reversed: Vec<u32> = (0..inside.len() as u32).rev().collect();
        outside.permute(&reversed).unwrap();
        pool.install(|| crate::region::team(|| inside.permute_unchecked(&reversed)));
        assert_eq!(inside.ids(), outside.ids());
        assert_eq!(inside.positions(), outside.positions());
        assert_eq!(inside.colour_laplacians(), outside.colour_laplacians());
    }

    #[test]
    fn disjoint_field_borrows() {
        let mut p = three();
        let f = p.fields_mut();
        for (a, x) in f.accelerations.iter_mut().zip(f.positions.iter()) {
            *a = *x * 2.0;
        }
        assert_eq!(p.accelerations()[2], Vec3::splat(4.0));
        let q = p.clone();
        assert_eq!(q.accelerations(), p.accelerations());
    }
}
