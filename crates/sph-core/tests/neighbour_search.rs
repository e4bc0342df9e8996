//! The neighbour grid against brute force O(N²), on random, clustered and
//! degenerate particle sets (property tests), and its error cases.

use glam::Vec3;
use proptest::prelude::*;
use sph_core::{Error, NeighbourGrid};

/// |a − b|² exactly as the grid evaluates it.
fn dist2(a: Vec3, b: Vec3) -> f32 {
    let d = a - b;
    d.x * d.x + d.y * d.y + d.z * d.z
}

fn brute_force(positions: &[Vec3], x: Vec3, h: f32) -> Vec<usize> {
    (0..positions.len())
        .filter(|&j| dist2(x, positions[j]) <= h * h)
        .collect()
}

/// Asserts the grid's particle and point queries equal brute force, that every
/// reported offset and r² is right, and that `par_map` agrees with the serial query.
fn check_against_brute_force(positions: &[Vec3], h: f32, probes: &[Vec3]) {
    let grid = NeighbourGrid::build(positions, h).expect("valid input");
    assert_eq!(grid.len(), positions.len());
    let counts = grid.par_map(|_, nb| nb.count());
    for (i, &x) in positions.iter().enumerate() {
        let mut found = Vec::new();
        grid.for_each_neighbour(i, |j, d, r2| {
            assert_eq!(d, x - positions[j], "offset of {j} from {i}");
            assert_eq!(r2, dist2(x, positions[j]));
            found.push(j);
        });
        let mut sorted = found.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), found.len(), "particle {i}: a neighbour twice");
        assert_eq!(sorted, brute_force(positions, x, h), "particle {i} at {x}");
        assert_eq!(counts[i], found.len());
    }
    for &x in probes {
        let mut found = Vec::new();
        grid.for_each_neighbour_of_point(x, |j, d, _| {
            assert_eq!(d, x - positions[j]);
            found.push(j);
        });
        found.sort_unstable();
        assert_eq!(found, brute_force(positions, x, h), "point {x}");
    }
}

fn vec3_in(lo: f32, hi: f32) -> impl Strategy<Value = Vec3> {
    (lo..hi, lo..hi, lo..hi).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Uniformly random particles, possibly spread over many cells or few, around
    /// an offset origin (negative coordinates included).
    #[test]
    fn random_sets(
        h in 0.01f32..2.0,
        extent in 0.5f32..8.0,
        offset in vec3_in(-100.0, 100.0),
        unit in prop::collection::vec(vec3_in(-1.0, 1.0), 0..300),
        probes in prop::collection::vec(vec3_in(-1.2, 1.2), 0..20),
    ) {
        let positions: Vec<Vec3> = unit.iter().map(|&u| offset + u * extent * h).collect();
        let probes: Vec<Vec3> = probes.iter().map(|&u| offset + u * extent * h).collect();
        check_against_brute_force(&positions, h, &probes);
    }

    /// Dense clusters: many particles per cell next to empty space.
    #[test]
    fn clustered_sets(
        h in 0.05f32..1.0,
        centres in prop::collection::vec(vec3_in(-5.0, 5.0), 1..5),
        members in prop::collection::vec((0usize..5, vec3_in(-0.6, 0.6)), 1..300),
    ) {
        let positions: Vec<Vec3> = members
            .iter()
            .map(|&(c, u)| (centres[c % centres.len()] + u) * h)
            .collect();
        let probes: Vec<Vec3> = centres.iter().map(|&c| c * h).collect();
        check_against_brute_force(&positions, h, &probes);
    }

    /// Lattices whose points fall exactly on cell borders and exactly h apart.
    #[test]
    fn lattices_on_cell_borders(
        h in prop::sample::select(vec![0.25f32, 0.5, 1.0, 2.0, 0.1, 0.02]),
        per_h in 1usize..4,
        dims in (1usize..7, 1usize..7, 1usize..7),
        origin in prop::sample::select(vec![0.0f32, -3.0, 1024.0]),
    ) {
        let spacing = h / per_h as f32;
        let mut positions = Vec::new();
        for k in 0..dims.2 {
            for j in 0..dims.1 {
                for i in 0..dims.0 {
                    positions.push(Vec3::splat(origin * h) + Vec3::new(i as f32, j as f32, k as f32) * spacing);
                }
            }
        }
        check_against_brute_force(&positions, h, &[Vec3::splat(origin * h)]);
    }

    /// Thread count does not change results: identical order and bitwise sums.
    #[test]
    fn identical_for_1_and_4_threads(
        unit in prop::collection::vec(vec3_in(-1.0, 1.0), 1..400),
    ) {
        let positions: Vec<Vec3> = unit.iter().map(|&u| u * 3.0).collect();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
                let grid = NeighbourGrid::build(&positions, 0.7).unwrap();
                let sums = grid.par_map(|_, nb| {
                    let mut s = 0.0f32;
                    nb.for_each(|j, _, r2| s += r2 * (j as f32 + 1.0));
                    s.to_bits()
                });
                (grid.order().to_vec(), sums)
            })
        };
        prop_assert_eq!(run(1), run(4));
    }

    /// A grid rebuilt in place (from a dense, a sparse or an empty set) answers
    /// exactly like one built fresh on the new positions.
    #[test]
    fn rebuild_equals_build(
        first in prop::collection::vec(vec3_in(-1.0, 1.0), 0..300),
        second in prop::collection::vec(vec3_in(-1.0, 1.0), 0..300),
        spread in prop::sample::select(vec![1.0f32, 40.0]),
    ) {
        let h = 0.3;
        let old: Vec<Vec3> = first.iter().map(|&u| u * spread).collect();
        let new: Vec<Vec3> = second.iter().map(|&u| u * 2.0).collect();
        let mut grid = NeighbourGrid::build(&old, h).unwrap();
        grid.rebuild(&new).unwrap();
        let fresh = NeighbourGrid::build(&new, h).unwrap();
        prop_assert_eq!(grid.len(), fresh.len());
        prop_assert_eq!(grid.order(), fresh.order());
        let lists = |g: &NeighbourGrid| (0..new.len()).map(|i| {
            let mut v = Vec::new();
            g.for_each_neighbour(i, |j, _, r2| v.push((j, r2.to_bits())));
            v
        }).collect::<Vec<_>>();
        prop_assert_eq!(lists(&grid), lists(&fresh));
        let probe = Vec3::new(0.1, -0.2, 0.3);
        prop_assert_eq!(
            grid.neighbourhood_of_point(probe).count(),
            fresh.neighbourhood_of_point(probe).count()
        );
    }
}

/// Values in slot order: gathered through `order()`, and borrowed as they are
/// once the particles are numbered by slot.
#[test]
fn values_in_slot_order() {
    let positions: Vec<Vec3> = (0..50)
        .map(|i| Vec3::new((i * 7 % 13) as f32, (i % 5) as f32, (i * 3 % 11) as f32) * 0.3)
        .collect();
    let values: Vec<f32> = (0..50).map(|i| i as f32).collect();
    let mut grid = NeighbourGrid::build(&positions, 1.0).unwrap();
    let by_slot = grid.to_slot_order(&values);
    assert!(matches!(by_slot, std::borrow::Cow::Owned(_)));
    let gathered: Vec<f32> = grid.order().iter().map(|&i| values[i as usize]).collect();
    assert_eq!(*by_slot, gathered[..]);
    grid.renumber_by_slot();
    assert!(matches!(
        grid.to_slot_order(&gathered),
        std::borrow::Cow::Borrowed(_)
    ));
    grid.rebuild(&positions).unwrap();
    assert!(matches!(
        grid.to_slot_order(&values),
        std::borrow::Cow::Owned(_)
    ));
}

/// Thread count does not change a large grid: above 2 × 32,768 particles
/// the counting sort splits its input into one chunk per thread (1, 2 or 4
/// here), which the small property test above never reaches. Dense and
/// sparse cell tables both (one cube, and four cubes kilometres apart).
#[test]
fn large_sets_identical_for_1_2_and_4_threads() {
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let unit: Vec<Vec3> = (0..100_000)
        .map(|_| Vec3::new(next(), next(), next()))
        .collect();
    for spread in [0.0f32, 1000.0] {
        let positions: Vec<Vec3> = (unit.iter().enumerate())
            .map(|(i, &u)| u + spread * Vec3::new((i % 4) as f32, (i % 3) as f32, 0.0))
            .collect();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let grid = NeighbourGrid::build(&positions, 0.03).unwrap();
                    let sums = grid.par_map(|_, nb| {
                        let mut s = 0.0f32;
                        nb.for_each(|j, _, r2| s += r2 * (j as f32 + 1.0));
                        s.to_bits()
                    });
                    (grid.order().to_vec(), sums)
                })
        };
        let one = run(1);
        assert!(
            one.1.iter().any(|&s| s != 0),
            "spread {spread}: no neighbours"
        );
        assert_eq!(one, run(2), "spread {spread}");
        assert_eq!(one, run(4), "spread {spread}");
    }
}

#[test]
fn degenerate_sets() {
    let h = 0.1;
    // Empty.
    let grid = NeighbourGrid::build(&[], h).unwrap();
    assert!(grid.is_empty());
    assert_eq!(grid.neighbourhood_of_point(Vec3::ZERO).count(), 0);
    assert!(grid.par_map(|_, nb| nb.count()).is_empty());
    // One particle.
    check_against_brute_force(
        &[Vec3::new(0.3, -0.2, 7.0)],
        h,
        &[Vec3::new(0.3, -0.2, 7.05)],
    );
    // All coincident: everyone neighbours everyone.
    let same = vec![Vec3::splat(0.05); 200];
    check_against_brute_force(&same, h, &[Vec3::splat(0.05)]);
    let grid = NeighbourGrid::build(&same, h).unwrap();
    assert_eq!(grid.neighbourhood(17).count(), 200);
    assert_eq!(grid.cell_count(), 1);
    // A line and a plane.
    let line: Vec<Vec3> = (0..100).map(|i| Vec3::X * (i as f32 * 0.03)).collect();
    check_against_brute_force(&line, h, &[]);
    let plane: Vec<Vec3> = (0..400)
        .map(|i| Vec3::new((i % 20) as f32 * 0.04, 0.0, (i / 20) as f32 * 0.04))
        .collect();
    check_against_brute_force(&plane, h, &[]);
}

#[test]
fn huge_coordinates() {
    // At 1e7 m an f32 step is 1 m: use h = 4 and a lattice of spacing 2 far away,
    // plus one particle at the origin: memory stays O(particles).
    let far = Vec3::new(1e7, -1e7, 1e7);
    let mut positions: Vec<Vec3> = (0..64)
        .map(|i| far + Vec3::new((i % 4) as f32, ((i / 4) % 4) as f32, (i / 16) as f32) * 2.0)
        .collect();
    positions.push(Vec3::ZERO);
    check_against_brute_force(&positions, 4.0, &[far, Vec3::ZERO, Vec3::splat(5e6)]);
    let grid = NeighbourGrid::build(&positions, 4.0).unwrap();
    // Exactly the occupied cells are stored, not the 1e7 m box between
    // (cells are h (1 + 1e-5) wide, see the grid module's docs).
    let edge = 4.0 * (1.0 + 1e-5);
    let occupied: std::collections::HashSet<[i64; 3]> = (positions.iter())
        .map(|x| (x.as_dvec3() / edge).floor().as_i64vec3().to_array())
        .collect();
    assert_eq!(grid.cell_count(), occupied.len());
    // A query point far beyond anything representable in cells finds nothing.
    assert_eq!(grid.neighbourhood_of_point(Vec3::splat(1e30)).count(), 0);
    assert_eq!(grid.neighbourhood_of_point(Vec3::NAN).count(), 0);
}

#[test]
fn bad_input_is_an_error() {
    let ok = [Vec3::ZERO, Vec3::ONE];
    for h in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let e = NeighbourGrid::build(&ok, h).unwrap_err();
        assert!(
            matches!(e, Error::InvalidParameter { name: "h", .. }),
            "{e}"
        );
    }
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let positions = [
            Vec3::ZERO,
            Vec3::ONE,
            Vec3::new(0.0, bad, 0.0),
            Vec3::splat(bad),
        ];
        let e = NeighbourGrid::build(&positions, 0.5).unwrap_err();
        assert!(
            matches!(e, Error::NonFinitePosition { index: 2, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("particle 2"), "{e}");
    }
    // Finite but too far for the cell size: a clear error, not a wrapped cell.
    let e = NeighbourGrid::build(&[Vec3::ZERO, Vec3::new(3e38, 0.0, 0.0)], 1e-3).unwrap_err();
    assert!(matches!(e, Error::OutOfGridRange { index: 1, .. }), "{e}");
}
