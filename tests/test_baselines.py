"""Behaviour of the baselines: none, temporal-copy, lozes-pde, meshlab.

Synthetic surfaces with known geometry (plane, sphere, a bumpy height field that has no symmetry for
ICP to slide along), so every fill can be checked against the true surface.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods.lozes_pde import LozesPDE, sampling_step
from dpcbench.methods.meshlab import MeshlabError, MeshlabFill, cluster_points, sample_triangles
from dpcbench.methods.reference import NoFill, TemporalCopy, icp_align, median_neighbour_distance


def rotation_about_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_xyz(ax: float, ay: float, az: float) -> np.ndarray:
    cx, sx, cy, sy = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    return rotation_about_z(az) @ ry @ rx


def bump_height(x, y):
    """z of the bumpy test surface: three Gaussian bumps (no symmetry for ICP to slide along)."""
    return (0.15 * np.exp(-((x - 0.3) ** 2 + (y - 0.4) ** 2) / 0.02)
            + 0.10 * np.exp(-((x - 0.7) ** 2 + (y - 0.6) ** 2) / 0.05)
            - 0.08 * np.exp(-((x - 0.5) ** 2 + (y - 0.2) ** 2) / 0.01))


def bumpy_height_field(n_side: int = 60, size: float = 1.0, seed: int = 0) -> np.ndarray:
    """Grid-sampled `bump_height` over [0, size]^2, jittered in x, y: (n_side^2, 3)."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, size, n_side)
    x, y = np.meshgrid(u, u, indexing="ij")
    step = size / (n_side - 1)
    x = x + rng.uniform(-0.2, 0.2, x.shape) * step
    y = y + rng.uniform(-0.2, 0.2, y.shape) * step
    return np.column_stack([x.ravel(), y.ravel(), bump_height(x, y).ravel()])


def symmetric_coverage(result: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(max distance truth -> result, max distance result -> truth)."""
    return float(cKDTree(result).query(truth)[0].max()), float(cKDTree(truth).query(result)[0].max())


# -- none ------------------------------------------------------------------------------------------

def test_none_returns_equal_copies():
    frames = [bumpy_height_field(20, seed=s) for s in range(3)]
    out = NoFill().inpaint(frames, [[HoleRegion.ball([0.5, 0.5, 0.0], 0.2)]] * 3)
    assert len(out) == 3
    for a, b in zip(out, frames):
        np.testing.assert_array_equal(a, b)
        assert a is not b and not np.shares_memory(a, b)
    # blind protocol: nothing to detect when nothing is filled
    assert all(np.array_equal(a, b) for a, b in zip(NoFill().inpaint(frames), frames))


# -- rigid alignment helpers -----------------------------------------------------------------------

def test_icp_recovers_a_small_motion_of_an_asymmetric_surface():
    surface = bumpy_height_field(40)
    # point-to-point ICP finds small motions (here about 0.3 spacings) exactly
    rotation, translation = rotation_xyz(0.01, -0.01, 0.01), np.array([0.005, -0.005, 0.005])
    moved = surface @ rotation.T + translation
    r, t = icp_align(surface, moved, max_distance=0.2, max_iterations=100)
    np.testing.assert_allclose(r, rotation, atol=1e-8)
    np.testing.assert_allclose(surface @ r.T + t, moved, atol=1e-8)
    # no iterations or too few points: identity
    r0, t0 = icp_align(surface, moved, max_distance=0.2, max_iterations=0)
    np.testing.assert_array_equal(r0, np.eye(3))
    np.testing.assert_array_equal(t0, np.zeros(3))


def test_median_neighbour_distance_of_a_regular_grid():
    u = np.arange(10) * 0.5
    grid = np.stack(np.meshgrid(u, u, [0.0], indexing="ij"), axis=-1).reshape(-1, 3)
    assert median_neighbour_distance(grid) == pytest.approx(0.5)


# -- temporal-copy ---------------------------------------------------------------------------------

def frame_motion(f: int) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motion (R, t) of frame f of `rigid_sequence`: about 3 point spacings per frame."""
    return rotation_xyz(0.02 * f, -0.015 * f, 0.04 * f), np.array([0.01, 0.02, -0.01]) * f


def rigid_sequence(n_frames: int = 3):
    """The same bumpy surface moved rigidly a little from frame to frame (intact frames)."""
    surface = bumpy_height_field(60)
    return [surface @ r.T + t for r, t in (frame_motion(f) for f in range(n_frames))]


def off_surface(points: np.ndarray, f: int) -> np.ndarray:
    """|z - bump_height(x, y)| of frame-f points taken back to the surface's own coordinates."""
    rotation, translation = frame_motion(f)
    local = (points - translation) @ rotation
    return np.abs(local[:, 2] - bump_height(local[:, 0], local[:, 1]))


def test_temporal_copy_reproduces_a_hole_of_a_rigidly_moving_surface():
    intact = rigid_sequence(3)
    region = HoleRegion.ball(intact[1][1830], 0.12)  # interior point near the middle of the patch
    hole = region.contains(intact[1])
    assert 50 < hole.sum() < 0.2 * len(intact[1])
    damaged = [intact[0], intact[1][~hole], intact[2]]
    out = TemporalCopy().inpaint(damaged, [[], [region], []])
    np.testing.assert_array_equal(out[0], intact[0])
    np.testing.assert_array_equal(out[2], intact[2])
    # the original points come first, untouched
    np.testing.assert_array_equal(out[1][: len(damaged[1])], damaged[1])
    filled = out[1][len(damaged[1]):]
    assert region.contains(filled).all()
    truth = intact[1][hole]
    spacing = median_neighbour_distance(intact[1])
    # the copy lies near the true surface and covers the hole without gaps. Not exactly: the rim of
    # a nearly flat hole lets point-to-point ICP stop about half a spacing off (measured: mean 0.13,
    # max 0.55 spacings; without ICP mean 0.70, max 1.41)
    assert off_surface(filled, 1).mean() < 0.25 * spacing and off_surface(filled, 1).max() < 0.8 * spacing
    to_result, to_truth = symmetric_coverage(filled, truth)
    assert to_result < 1.5 * spacing and to_truth < 1.5 * spacing
    # without alignment the copy is visibly off the surface: ICP is what makes it right
    unaligned = TemporalCopy(icp_iterations=0).inpaint(damaged, [[], [region], []])[1][len(damaged[1]):]
    assert off_surface(unaligned, 1).mean() > 0.5 * spacing


def test_temporal_copy_takes_the_neighbour_with_more_points_in_the_hole():
    intact = rigid_sequence(3)
    region = HoleRegion.ball(intact[1][1830], 0.12)
    # frame 0 has the same hole (fewer points in the region), so frame 2 must be the source
    damaged = [intact[0][~region.contains(intact[0])], intact[1][~region.contains(intact[1])], intact[2]]
    out = TemporalCopy().inpaint(damaged, [[region], [region], []])
    truth = intact[1][region.contains(intact[1])]
    filled = out[1][len(damaged[1]):]
    spacing = median_neighbour_distance(intact[1])
    assert off_surface(filled, 1).mean() < 0.25 * spacing and off_surface(filled, 1).max() < 0.8 * spacing
    assert max(symmetric_coverage(filled, truth)) < 1.5 * spacing
    # frame 0 is filled from frame 1, whose region is empty too: left as it is
    np.testing.assert_array_equal(out[0], damaged[0])


def test_temporal_copy_one_frame_warns_and_returns_input():
    frame = bumpy_height_field(20)
    with pytest.warns(RuntimeWarning, match="one-frame"):
        out = TemporalCopy().inpaint([frame], [[HoleRegion.ball([0.5, 0.5, 0], 0.1)]])
    np.testing.assert_array_equal(out[0], frame)


def test_temporal_copy_rejects_bad_parameters_and_inputs():
    frames = rigid_sequence(2)
    with pytest.raises(ValueError, match="shell_factor"):
        TemporalCopy(shell_factor=-1).inpaint(frames, [[], []])
    with pytest.raises(ValueError, match="region lists"):
        TemporalCopy().inpaint(frames, [[]])
    bad = frames[1].copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        TemporalCopy().inpaint([frames[0], bad], [[], []])


# -- lozes-pde -------------------------------------------------------------------------------------


def tilted_plane(n: int = 12000, seed: int = 0) -> tuple[np.ndarray, np.ndarray, float]:
    """Random samples of the plane n.x = d over a 60 x 60 patch: (points (n, 3), unit normal, d)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, 60.0, (n, 2))
    points = np.column_stack([xy, 0.3 * xy[:, 0] - 0.2 * xy[:, 1] + 5.0])
    normal = np.array([0.3, -0.2, -1.0])
    return points, normal / np.linalg.norm(normal), 5.0 / -np.linalg.norm(normal)


def fibonacci_sphere(n: int, radius: float) -> np.ndarray:
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    return radius * np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])


def test_sampling_step_matches_the_density_of_a_grid_and_of_random_samples():
    u = np.arange(120.0)
    grid = np.stack(np.meshgrid(u, u, [0.0], indexing="ij"), axis=-1).reshape(-1, 3)
    assert sampling_step(grid) == pytest.approx(1.0, rel=0.05)
    points, _, _ = tilted_plane()
    area = 60.0 * 60.0 * np.sqrt(1 + 0.3 ** 2 + 0.2 ** 2)  # true area of the sampled patch
    assert sampling_step(points) == pytest.approx(np.sqrt(area / len(points)), rel=0.1)


@pytest.mark.parametrize("p", [2, 1])
@pytest.mark.parametrize("solver", ["direct", "jacobi"])
def test_lozes_fills_a_planar_hole_onto_the_plane(p, solver):
    points, normal, offset = tilted_plane()
    region = HoleRegion.ball(points[np.argmin(np.linalg.norm(points[:, :2] - 30.0, axis=1))], 8.0)
    hole = region.contains(points)
    damaged = points[~hole]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a "did not converge" warning fails the test
        out = LozesPDE(p=p, solver=solver, max_iterations=3000).inpaint([damaged], [[region]])[0]
    np.testing.assert_array_equal(out[: len(damaged)], damaged)  # known points stay as they were
    new = out[len(damaged):]
    step = sampling_step(damaged)
    assert np.abs(new @ normal - offset).max() < 1e-6 * step
    assert region.contains(new, margin=2 * step).all()  # seeds reach half the 3-step ring into it
    # the new points cover the hole at about the data's density
    truth = points[hole]
    assert cKDTree(new).query(truth)[0].max() < 2.0 * step  # seeds keep 0.8 step off the rim
    assert 0.7 * len(truth) < len(new) < 1.3 * len(truth)


@pytest.mark.parametrize("p", [2, 1])
def test_lozes_fills_a_sphere_cap_near_the_sphere(p):
    radius = 100.0
    sphere = fibonacci_sphere(30000, radius)
    region = HoleRegion.ball(sphere[np.argmax(sphere[:, 2])], 20.0)
    hole = region.contains(sphere)
    out = LozesPDE(p=p).inpaint([sphere[~hole]], [[region]])[0]
    new = out[(~hole).sum():]
    radial = np.linalg.norm(new, axis=1) - radius
    # the p-Laplacian with the rim fixed makes a nearly flat patch: it stays between the rim's
    # plane and the cap, so no point is farther from the sphere than the cap's sagitta
    sagitta = radius - np.sqrt(radius ** 2 - region.radius ** 2 * (1 - region.radius ** 2 / (4 * radius ** 2)))
    assert radial.max() <= 0.05 * sagitta and radial.min() >= -1.1 * sagitta
    assert cKDTree(new).query(sphere[hole])[0].max() < sagitta + 1.5 * sampling_step(sphere)


def test_lozes_jacobi_reaches_the_direct_solution():
    sphere = fibonacci_sphere(20000, 100.0)
    region = HoleRegion.ball(sphere[np.argmax(sphere[:, 0])], 15.0)
    damaged = [sphere[~region.contains(sphere)]]
    direct = LozesPDE(solver="direct").inpaint(damaged, [[region]])[0]
    jacobi = LozesPDE(solver="jacobi", tolerance=1e-6, max_iterations=20000).inpaint(damaged, [[region]])[0]
    assert direct.shape == jacobi.shape
    assert np.abs(direct - jacobi).max() < 0.05 * sampling_step(damaged[0])


def test_lozes_warns_when_not_converged_and_rejects_bad_parameters():
    sphere = fibonacci_sphere(8000, 100.0)
    region = HoleRegion.ball(sphere[0], 20.0)
    damaged = [sphere[~region.contains(sphere)]]
    with pytest.warns(RuntimeWarning, match="did not converge"):
        LozesPDE(solver="jacobi", max_iterations=2).inpaint(damaged, [[region]])
    for bad in ({"p": 3}, {"solver": "cg"}, {"k_neighbours": 1}, {"tolerance": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            LozesPDE(**bad).inpaint(damaged, [[region]])
    with pytest.raises(ValueError, match="max_new_points"):
        LozesPDE(max_new_points=10).inpaint(damaged, [[region]])


def test_lozes_leaves_a_region_without_surface_alone():
    sphere = fibonacci_sphere(8000, 100.0)
    far = HoleRegion.ball([500.0, 0.0, 0.0], 10.0)
    np.testing.assert_array_equal(LozesPDE().inpaint([sphere], [[far]])[0], sphere)


# -- meshlab ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def holed_sphere():
    """(damaged (N, 3), hole points (H, 3), region): a 5000-point sphere of radius 50 with a ball hole."""
    sphere = fibonacci_sphere(5000, 50.0)
    region = HoleRegion.ball(sphere[np.argmax(sphere @ np.array([0.3, 0.5, 0.8]))], 9.0)
    hole = region.contains(sphere)
    return sphere[~hole], sphere[hole], region


def test_sample_triangles_is_uniform_and_seeded():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0], [3, 3, 0]])
    faces = np.array([[0, 1, 2], [1, 3, 4]])  # areas 0.5 and 3
    samples = sample_triangles(vertices, faces, 7000, np.random.default_rng(5))
    in_small = samples[:, 0] + samples[:, 1] <= 1.0
    assert in_small.mean() == pytest.approx(0.5 / 3.5, abs=0.02)
    assert np.allclose(samples[:, 2], 0.0)
    np.testing.assert_array_equal(samples, sample_triangles(vertices, faces, 7000, np.random.default_rng(5)))


@pytest.mark.parametrize("reconstruction", ["ball-pivoting", "poisson"])
def test_meshlab_holes_only_keeps_every_point_and_adds_only_in_the_hole(holed_sphere, reconstruction):
    damaged, truth, region = holed_sphere
    out = MeshlabFill(output="holes-only", reconstruction=reconstruction).inpaint([damaged], [[region]])[0]
    np.testing.assert_array_equal(out[: len(damaged)], damaged)
    added = out[len(damaged):]
    step = sampling_step(damaged)
    assert 0.5 * len(truth) < len(added) < 1.5 * len(truth)
    assert region.contains(added, margin=2 * step).all()
    # the patch is close to the sphere (within the hole's sagitta) and covers the hole
    sagitta = 50.0 - np.sqrt(50.0 ** 2 - region.radius ** 2)
    assert np.abs(np.linalg.norm(added, axis=1) - 50.0).max() < 1.5 * sagitta
    assert cKDTree(added).query(truth)[0].max() < sagitta + 2 * step


def test_meshlab_meshes_a_frame_in_metres_as_in_millimetres():
    """MeshLab's ball pivoting holds tolerances in absolute units (handed the frame in its own units, the human
    stand-in scaled by 2^-10 gave 23,299 points instead of 23,304); the adapter hands it the frame in units of its
    sampling step, so the same frame scaled by a power of two (exact in floating point) gives the same output."""
    from dpcbench.bench.data.datasets import load_dataset

    frame = load_dataset("human", frames=1, size="tiny", progress=False).points[0] * 1.37  # float, not voxels
    centres = frame[np.random.default_rng(1).choice(len(frame), 3, replace=False)]
    regions = [HoleRegion.ball(c, 10.0) for c in centres]
    damaged = frame[~np.any([r.contains(frame) for r in regions], axis=0)]
    scale = 2.0 ** -10
    fill = MeshlabFill(output="holes-only")
    out = fill.inpaint([damaged], [regions])[0]
    scaled = fill.inpaint([damaged * scale], [[r.scaled(scale) for r in regions]])
    np.testing.assert_array_equal(scaled[0] / scale, out)


def test_meshlab_blind_holes_only_fills_the_hole_too(holed_sphere):
    damaged, truth, region = holed_sphere
    out = MeshlabFill(output="holes-only").inpaint([damaged], None)[0]
    added = out[len(damaged):]
    assert region.contains(added, margin=2 * sampling_step(damaged)).sum() > 0.5 * len(truth)


def test_meshlab_whole_resamples_the_same_count_on_the_surface(holed_sphere):
    damaged, truth, region = holed_sphere
    out = MeshlabFill(output="whole").inpaint([damaged], [[region]])[0]
    assert len(out) == len(damaged)  # the same point count, spread over the closed mesh
    assert cKDTree(damaged).query(out)[0].min() > 0  # every point resampled, none copied
    assert np.abs(np.linalg.norm(out, axis=1) - 50.0).max() < 2.0
    # the hole is covered too
    assert cKDTree(out).query(truth)[0].max() < 2 * sampling_step(damaged)


def test_cluster_points_caps_the_count_and_stays_on_the_surface():
    sphere = fibonacci_sphere(20000, 50.0)
    assert cluster_points(sphere, 20000, 1.2)[0] is sphere  # small frames are used as they are
    clustered, none = cluster_points(sphere, 4000, sampling_step(sphere))
    assert none is None
    assert 2500 < len(clustered) <= 4000
    assert np.abs(np.linalg.norm(clustered, axis=1) - 50.0).max() < 0.5  # cell means lie on the sphere
    assert cKDTree(clustered).query(sphere)[0].max() < 3 * sampling_step(clustered)  # and cover it


@pytest.mark.parametrize("output", ["whole", "holes-only"])
def test_meshlab_reconstructs_large_frames_from_clustered_points(output):
    """Above max_points the mesh comes from a clustered copy; the output keeps its meaning: the input
    count on the closed surface (whole), or the input plus points in the hole only (holes-only)."""
    sphere = fibonacci_sphere(12000, 50.0)
    region = HoleRegion.ball(sphere[np.argmax(sphere @ np.array([0.3, 0.5, 0.8]))], 9.0)
    hole = region.contains(sphere)
    damaged, truth = sphere[~hole], sphere[hole]
    step = sampling_step(damaged)
    out = MeshlabFill(output=output, max_points=4000).inpaint([damaged], [[region]])[0]
    if output == "whole":
        assert len(out) == len(damaged)
        assert np.abs(np.linalg.norm(out, axis=1) - 50.0).max() < 2.0
        assert cKDTree(out).query(truth)[0].max() < 3 * step
    else:
        np.testing.assert_array_equal(out[: len(damaged)], damaged)
        added = out[len(damaged):]
        assert 0.5 * len(truth) < len(added) < 1.5 * len(truth)
        assert region.contains(added, margin=2 * step).all()
    with pytest.raises(ValueError, match="max_points"):
        MeshlabFill(max_points=10).inpaint([damaged], [[region]])


def test_meshlab_failures_are_clear_errors(holed_sphere):
    damaged, _, region = holed_sphere
    with pytest.raises(MeshlabError, match="produced no faces"):
        MeshlabFill(ball_radius=1e-4).inpaint([damaged], [[region]])
    line = np.column_stack([np.linspace(0.0, 1.0, 200), np.zeros(200), np.zeros(200)])
    with pytest.raises(MeshlabError, match="ball-pivoting"):
        MeshlabFill().inpaint([line], [[HoleRegion.ball([0.5, 0, 0], 0.1)]])
    for bad in ({"output": "mesh"}, {"reconstruction": "alpha"}, {"max_hole_size": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            MeshlabFill(**bad).inpaint([damaged], [[region]])
    assert issubclass(MeshlabError, RuntimeError)


# -- blind protocol (regions=None: holes.detection.detect_holes finds the hole) --------------------

def test_blind_lozes_and_temporal_copy_fill_the_detected_hole():
    sphere = fibonacci_sphere(5000, 50.0)
    region = HoleRegion.ball(sphere[np.argmax(sphere[:, 2])], 11.0)
    hole = region.contains(sphere)
    added = LozesPDE().inpaint([sphere[~hole]])[0][(~hole).sum():]
    assert 0.7 * hole.sum() < len(added) and region.contains(added, margin=3.0).all()

    def tilt(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    frames = [sphere @ tilt(a).T for a in (0.0, 0.02, 0.04)]
    region = HoleRegion.ball(frames[1][np.argmax(frames[1][:, 2])], 11.0)
    hole = region.contains(frames[1])
    damaged = [frames[0], frames[1][~hole], frames[2]]
    out = TemporalCopy().inpaint(damaged)
    assert [len(o) - len(d) for o, d in zip(out, damaged)][::2] == [0, 0]
    added = out[1][len(damaged[1]):]
    assert len(added) > 0.8 * hole.sum()
    assert cKDTree(frames[1]).query(added)[0].max() < 0.5 * sampling_step(frames[1])


def _gradient(points: np.ndarray) -> np.ndarray:
    """A colour linear in the coordinates (of a sphere of radius 50 round the origin), float 0..255."""
    return np.clip(np.column_stack([127.5 + 2.4 * points[:, 0], 127.5 + 2.4 * points[:, 1], 127.5 + 2.4 * points[:, 2]]),
                   0, 255)


@pytest.mark.parametrize("output, max_points", [("whole", 120_000), ("holes-only", 120_000), ("whole", 4000)])
def test_meshlab_colours_are_meshlab_s_vertex_colours_interpolated(output, max_points):
    """A colour linear in position: MeshLab's vertex colours (the input's, or the clustered cells' means)
    interpolated at the samples reproduce it to a few levels (linear interpolation of a linear function on
    triangles that lie on the sphere), kept points keep theirs, and the geometry is ``inpaint``'s."""
    sphere = fibonacci_sphere(8000, 50.0)
    region = HoleRegion.ball(sphere[np.argmax(sphere @ np.array([0.3, 0.5, 0.8]))], 9.0)
    damaged = sphere[~region.contains(sphere)]
    colours = np.rint(_gradient(damaged)).astype(np.uint8)
    method = MeshlabFill(output=output, max_points=max_points)
    points, cols = method.inpaint_with_colours([damaged], [colours], [[region]])
    np.testing.assert_array_equal(points[0], MeshlabFill(output=output, max_points=max_points).inpaint(
        [damaged], [[region]])[0])
    assert cols[0].shape == (len(points[0]), 3) and cols[0].dtype == np.uint8
    error = np.abs(cols[0].astype(float) - _gradient(points[0]))
    assert error.mean() < 0.6 and error.max() < 3  # nearest-input colours: 0.97 / 17.4 here
    if output == "holes-only":
        np.testing.assert_array_equal(cols[0][:len(damaged)], colours)
        assert len(points[0]) > len(damaged)
