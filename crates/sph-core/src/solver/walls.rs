//! The walls' share of a particle's density for the incompressible solvers
//! (PBF, DFSPH): the analytic density of the fluid behind the domain walls
//! and obstacles within h ([`WallKernel`]) and its gradient, with the
//! half-spaces of meeting walls united rather than added.

use glam::Vec3;

use crate::boundary::{Boundary, Layers, WallKernel};

/// The walls of a boundary, seen by a fluid of one density kernel and rest
/// density ρ0.
#[derive(Debug, Clone)]
pub(crate) struct Walls {
    boundary: Boundary,
    kernel: WallKernel,
    rest_density: f32,
}

impl Walls {
    /// The walls of `boundary` for a fluid whose density sums `kernel`
    /// integrates, of rest density `rest_density`.
    pub(crate) fn new(boundary: Boundary, kernel: WallKernel, rest_density: f32) -> Self {
        Self {
            boundary,
            kernel,
            rest_density,
        }
    }

    /// The boundary.
    pub(crate) fn boundary(&self) -> &Boundary {
        &self.boundary
    }

    /// The fluid's kernel, as the walls integrate it.
    pub(crate) fn kernel(&self) -> &WallKernel {
        &self.kernel
    }

    /// The layers of the lattice of the lightest of `masses`
    /// ([`lightest_layers`]).
    pub(crate) fn layers(&self, masses: &[f32], cache: &mut LayersCache) -> Option<Layers> {
        lightest_layers(&self.kernel, self.rest_density, masses, cache)
    }

    /// The walls' density term at `x` and its gradient over ρ0,
    /// ∇(ρ_wall/ρ0).
    ///
    /// Where walls meet, the fluid behind them is the union of their
    /// half-spaces. Its kernel-weighted volume is taken as
    /// f = 1 − Π_k (1 − f_k) over the walls' own fractions f_k
    /// ([`WallKernel::volume_fraction`]): exact for one wall, for an edge
    /// (¾) and a corner (⅞) of perpendicular walls at distance 0 and far
    /// from them, where WCSPH's sum Σ f_k counts the region behind two walls
    /// twice (see [`crate::boundary`]). Pushing against that excess is what
    /// would empty the edges of a tank.
    #[inline(always)]
    pub(crate) fn at(&self, x: Vec3) -> (f32, Vec3) {
        self.united(x, |d| self.kernel.fraction_and_density(d))
    }

    /// [`Self::at`] with each wall the fluid's lattice continued behind it
    /// in `layers` ([`WallKernel::layers_fraction_and_density`]): the walls
    /// under a clearance, where a lattice filled to the walls starts at
    /// rest density.
    #[inline]
    pub(crate) fn at_layers(&self, x: Vec3, layers: Layers) -> (f32, Vec3) {
        self.united(x, |d| self.kernel.layers_fraction_and_density(d, layers))
    }

    /// [`Self::at_layers`] in `layers`, or [`Self::at`] without.
    #[inline]
    pub(crate) fn at_either(&self, x: Vec3, layers: Option<Layers>) -> (f32, Vec3) {
        match layers {
            Some(layers) => self.at_layers(x, layers),
            None => self.at(x),
        }
    }

    /// The union of the walls within h of `x`, each of fraction and slope
    /// `wall(d)` at distance d.
    #[inline(always)]
    fn united(&self, x: Vec3, wall: impl Fn(f32) -> (f32, f32)) -> (f32, Vec3) {
        // Far from every wall (the bulk of most scenes): nothing, said in
        // two compares, as the walls' loop below would say it.
        let (b, h) = (&self.boundary, Vec3::splat(self.kernel.h()));
        let far = (x - b.domain.min).cmpge(h).all() && (b.domain.max - x).cmpge(h).all();
        if far && b.obstacles.is_empty() {
            return (0.0, Vec3::ZERO);
        }
        // Up to 8 walls (6 domain walls and obstacles): (1 − f_k, ∇f_k).
        let mut walls = [(1.0f32, Vec3::ZERO); 8];
        let mut count = 0;
        let mut extra = (0.0, Vec3::ZERO); // beyond 8 walls: summed
        self.boundary
            .for_each_wall_within(x, self.kernel.h(), |d, n| {
                let (f, density) = wall(d);
                let grad = -density * n;
                if count < walls.len() {
                    walls[count] = (1.0 - f, grad);
                    count += 1;
                } else {
                    extra = (extra.0 + f, extra.1 + grad);
                }
            });
        let walls = &walls[..count];
        let outside: f32 = walls.iter().map(|w| w.0).product();
        let mut grad = extra.1;
        for (k, &(_, g)) in walls.iter().enumerate() {
            let others: f32 = (walls.iter().enumerate())
                .filter(|&(l, _)| l != k)
                .map(|(_, w)| w.0)
                .product();
            grad += others * g;
        }
        (self.rest_density * (1.0 - outside + extra.0), grad)
    }
}

/// The last lightest mass and its layers.
pub(crate) type LayersCache = Option<(f32, Layers)>;

/// The walls' layers under a clearance ([`WallKernel::lattice_layers`]) for
/// the lattice of the lightest of `masses`, which every particle near a wall
/// sees; kept in `cache` while that mass stays the same. None without a
/// particle.
pub(crate) fn lightest_layers(
    kernel: &WallKernel,
    rest_density: f32,
    masses: &[f32],
    cache: &mut LayersCache,
) -> Option<Layers> {
    let lightest = super::lanes::lightest(masses);
    if !lightest.is_finite() {
        return None;
    }
    match *cache {
        Some((m, layers)) if m == lightest => Some(layers),
        _ => {
            let layers = kernel.lattice_layers(lightest, rest_density);
            *cache = Some((lightest, layers));
            Some(layers)
        }
    }
}
