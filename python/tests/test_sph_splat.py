"""sph_splat from Python: worlds, stepping, particle files and surfels as
numpy arrays, and bad input as exceptions naming the argument or field."""

import pathlib

import numpy as np
import pytest

import sph_splat as ss

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "splashsurf"


def test_a_dam_break_runs_from_python_within_its_density_error():
    world = ss.World("dam-break")
    assert world.solver == "pbf" and world.time == 0.0
    start = world.positions
    assert start.shape == (len(world), 3) and start.dtype == np.float32
    report = world.advance(0.2)
    assert abs(report["time"] - 0.2) < 1e-6
    assert report["solver"] == "pbf" and report["substeps"] == 3
    # The demo's PBF (3 substeps of 3 iterations a frame): about 1.4 %
    # average compression in the collapsing column, well under 10 % at most.
    assert 0.0 < report["density_error_avg"] < 0.02
    assert report["density_error_max"] < 0.2
    end = world.positions
    assert np.isfinite(end).all()
    assert end[:, 0].max() > start[:, 0].max() + 0.05, "the column collapses"
    densities = world.densities
    assert densities.shape == (len(world),)
    assert abs(np.median(densities) / 1000.0 - 1.0) < 0.02


def test_solvers_and_scene_files_choose_the_world():
    assert ss.World("dam-break", solver="dfsph").solver == "dfsph"
    world = ss.World(str(ROOT / "assets" / "scenes" / "dam_break_slab.toml"))
    assert world.solver == "pbf" and len(world) > 1000


def test_advance_steps_by_the_scenes_frame(tmp_path):
    # A scene whose frame is 1/20 s: one frame of 9 substeps of its PBF's
    # longest substep, 1/180 s, where frames of 1/60 s would end on 3.
    text = (ROOT / "assets" / "scenes" / "dam_break_slab.toml").read_text()
    text = text.replace("frame_dt = 0.016666668", "frame_dt = 0.05", 1)
    path = tmp_path / "slow_frames.toml"
    path.write_text(text)
    world = ss.World(str(path))
    report = world.advance(0.05)
    assert report["substeps"] == 9
    assert abs(report["time"] - 0.05) < 1e-6
    # Given, frame_dt wins.
    assert world.advance(0.05, frame_dt=1.0 / 60.0)["substeps"] == 3


def test_durations_that_are_not_whole_frames_end_on_time():
    # 0.15 s in frames of 0.1 s, or 0.7 s in one of 1 s: a remainder below
    # min_dt after f32 rounding once failed; equal frames take it.
    world = ss.World("dam-break")
    for seconds, frame_dt in [(0.15, 0.1), (0.7, 1.0), (0.4, 1.0 / 30.0), (0.31, 0.1)]:
        start = world.time
        report = world.advance(seconds, frame_dt=frame_dt)
        assert abs(world.time - start - seconds) < 1e-6
        assert isinstance(report["clamped"], int)
    # Equal frames: 0.15 s in frames of 0.1 s is two of 0.075 s, whose last
    # takes the substeps of one such frame (not those of a 0.05 s rest).
    last = ss.World("dam-break").advance(0.15, frame_dt=0.1)["substeps"]
    assert last == ss.World("dam-break").advance(0.075, frame_dt=0.1)["substeps"]
    assert last != ss.World("dam-break").advance(0.05, frame_dt=0.1)["substeps"]
    # A nanosecond or less takes no frame, as a loop towards a target time
    # may ask.
    start = world.time
    assert "substeps" not in world.advance(1e-10)
    assert world.time == start


def test_a_switch_that_gives_way_warns(tmp_path):
    # A DFSPH scene with a viscosity, run by PBF: its XSPH blend, which has
    # no viscosity, gives way to the implicit one, with a warning.
    text = (ROOT / "assets" / "scenes" / "dam_break_slab.toml").read_text()
    text = text.replace("rest_density = 1000.0\n", "rest_density = 1000.0\nviscosity = 0.001\n", 1)
    text = text.replace('kind = "pbf"', 'kind = "dfsph"', 1)
    path = tmp_path / "water.toml"
    path.write_text(text)
    with pytest.warns(UserWarning, match="implicitly"):
        world = ss.World(str(path), solver="pbf")
    assert world.solver == "pbf"


def test_a_world_from_arrays_falls_and_stays_in_its_box():
    grid = np.mgrid[0:6, 0:6, 0:6].reshape(3, -1).T.astype(np.float32)
    positions = 0.02 * grid + np.float32(0.2)
    world = ss.World.from_arrays(positions, 0.02, [0.0, 0.0, 0.0], [0.6, 0.6, 0.6])
    assert len(world) == 216
    world.advance(0.5)
    x = world.positions
    assert (x >= 0.0).all() and (x <= 0.6).all()
    assert x[:, 1].min() < 0.05, "it fell to the floor"
    # Velocities in and out.
    world.velocities = np.zeros((216, 3), np.float32)
    assert not world.velocities.any()


def test_particle_files_round_trip_through_numpy(tmp_path):
    rng = np.random.default_rng(7)
    positions = rng.random((100, 3), dtype=np.float32)
    velocities = rng.random((100, 3), dtype=np.float32)
    densities = rng.random(100, dtype=np.float32) + 999.0
    for ext in ["ply", "vtk"]:
        path = tmp_path / f"points.{ext}"
        ss.write_particles(path, positions, 1.25, velocities, densities)
        read, time = ss.read_particles(path)
        assert time == 1.25
        np.testing.assert_array_equal(read, positions)
    # Positions alone through the other simulators' formats.
    for ext in ["xyz", "vtu", "bgeo"]:
        path = tmp_path / f"points.{ext}"
        ss.write_particles(path, positions)
        read, time = ss.read_particles(path)
        assert time is None, ext
        np.testing.assert_array_equal(read, positions, err_msg=ext)
        with pytest.raises(ValueError, match="positions only"):
            ss.write_particles(path, positions, velocities=velocities)
    # XYZ is binary f32 triples, as splashsurf reads them.
    np.testing.assert_array_equal(
        np.fromfile(tmp_path / "points.xyz", np.float32).reshape(-1, 3), positions
    )
    # Other simulators' files.
    for name, count in [
        ("dam_break_frame_9_6859_particles.bgeo", 6859),
        ("double_dam_break_frame_01_4732_particles.vtk", 4732),
        ("fluid_encoded_250_particles.vtu", 250),
    ]:
        read, time = ss.read_particles(DATA / name)
        assert read.shape == (count, 3) and time is None and np.isfinite(read).all()


def test_surfels_of_a_world_and_of_arrays():
    world = ss.World("dam-break")
    surfels = world.extract()
    n = len(surfels["radii"])
    assert n > len(world), "more surfels than particles on a block"
    assert surfels["positions"].shape == (n, 3)
    normals = surfels["normals"]
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4)
    positions, _ = ss.read_particles(DATA / "dam_break_frame_9_6859_particles.bgeo")
    other = ss.extract(positions, 0.1)
    assert len(other["radii"]) > 1000
    assert len(ss.extract(positions, 0.1, surface="isotropic", iterations=1)["radii"]) > 1000


def test_bad_input_raises_naming_the_argument(tmp_path):
    with pytest.raises(ValueError, match="scene"):
        ss.World("no-such-scene")
    with pytest.raises(ValueError, match="solver"):
        ss.World("dam-break", solver="sph")
    world = ss.World("dam-break")
    with pytest.raises(ValueError, match="positions"):
        world.positions = np.zeros((len(world), 2), np.float32)
    with pytest.raises(ValueError, match="positions"):
        world.positions = np.zeros((3, 3), np.float32)
    bad = world.positions
    bad[5, 1] = np.nan
    with pytest.raises(ValueError, match="positions: row 5"):
        world.positions = bad
    outside = world.positions
    outside[7, 0] = -1.0
    with pytest.raises(ValueError, match="positions: row 7.*outside the domain"):
        world.positions = outside
    lattice = world.positions[:50]
    with pytest.raises(ValueError, match="domain_min"):
        ss.World.from_arrays(lattice, 0.02, [1.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="particle 0 has position"):
        ss.World.from_arrays(lattice + 5.0, 0.02, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="frame_dt"):
        world.advance(0.01, frame_dt=1e-40)
    with pytest.raises(ValueError, match="time"):
        ss.write_particles(tmp_path / "t.xyz", np.zeros((2, 3), np.float32), time=0.5)
    with pytest.raises(ValueError, match="density"):
        ss.write_particles(
            tmp_path / "nan.ply",
            np.zeros((2, 3), np.float32),
            densities=np.array([1000.0, np.nan], np.float32),
        )
    with pytest.raises(ValueError, match="seconds"):
        world.advance(float("nan"))
    with pytest.raises(ValueError, match="surface"):
        world.extract(surface="bumpy")
    with pytest.raises(ValueError, match="iterations"):
        world.extract(iterations=7)
    with pytest.raises(ValueError, match="positions"):
        ss.extract(np.zeros((4, 4), np.float32), 0.1)
    with pytest.raises(OSError, match="missing.vtk"):
        ss.read_particles(tmp_path / "missing.vtk")
    with pytest.raises(ValueError, match="format"):
        ss.write_particles(tmp_path / "points.txt", np.zeros((2, 3), np.float32))
    # A scene file's field, as sph-core names it.
    text = (ROOT / "assets" / "scenes" / "dam_break_slab.toml").read_text()
    broken = tmp_path / "broken.toml"
    broken.write_text(text.replace("h = 0.04", "h = -0.04", 1))
    with pytest.raises(ValueError, match="fluid.h"):
        ss.World(str(broken))
    # A surface tension force DFSPH does not have (the thesis's colour
    # field is WCSPH's only; DFSPH applies σ by Akinci et al.'s forces).
    sigma = tmp_path / "sigma.toml"
    sigma.write_text(
        text.replace(
            "surface_tension = 0.0",
            'surface_tension = 0.07\nsurface_tension_model = "colour-field"',
            1,
        ).replace('kind = "pbf"', 'kind = "dfsph"', 1)
    )
    with pytest.raises(ValueError, match="fluid.surface_tension_model"):
        ss.World(str(sigma))


def test_a_rendered_frame_has_its_shape_and_covers_the_fluid():
    world = ss.World("dam-break")
    world.advance(0.2)
    frame = world.render(160, 90)
    image = frame["image"]
    assert image.shape == (90, 160, 4) and image.dtype == np.uint8
    assert (image[:, :, 3] == 255).all(), "opaque"
    # The collapsing column fills part of the picture, not all of it.
    assert 0.05 < frame["covered"] < 0.6, frame["covered"]
    # Where the fluid is, the picture differs from the bare sky's.
    empty = ss.World.from_arrays(
        np.array([[10.0, 10.0, 10.0]], np.float32), 0.02, [0, 0, 0], [20, 20, 20]
    )
    assert empty.render(160, 90)["covered"] < frame["covered"]
    with pytest.raises(ValueError, match="width, height"):
        world.render(8, 8)
