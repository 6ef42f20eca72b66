"""locate_source, measure_scale, identify_spots and compute_scale_factor
against truth made independently (numpy geometry, simulated scenes)."""
import numpy as np
import pytest

import opl
from conftest import rotation_xyz


def equal_angle_directions(n, full_angle_rad):
    """Directions of the equal-angle pattern written out from docs/method:
    beam id = row * n + col + 1, row 0 top (el > 0), col 0 rightmost (az < 0)."""
    theta0 = full_angle_rad / (n - 1)
    ids, dirs = [], []
    for row in range(n):
        for col in range(n):
            # Spots on a plane x = 1 at tan(k theta0) from the centre in y and z.
            y = np.tan((col - (n - 1) / 2) * theta0)
            z = np.tan(((n - 1) / 2 - row) * theta0)
            d = np.array([1.0, y, z])
            ids.append(row * n + col + 1)
            dirs.append(d / np.linalg.norm(d))
    return np.array(ids), np.array(dirs)


def test_pattern_matches_the_method_numbering():
    pattern = opl.make_equal_angle_pattern(11, np.radians(29.0))
    ids, dirs = equal_angle_directions(11, np.radians(29.0))
    np.testing.assert_array_equal(pattern.ids, ids)
    np.testing.assert_allclose(pattern.directions, dirs, atol=1e-12)
    assert pattern.central_beam_id == 61
    # Beam 1 top right: elevation > 0, azimuth < 0 (+Y points left).
    assert pattern.el_rad[0] > 0 and pattern.az_rad[0] < 0


def test_locate_recovers_a_pose_built_in_numpy():
    rng = np.random.default_rng(7)
    pattern = opl.make_equal_angle_pattern(11, np.radians(29.0))
    ids, dirs = equal_angle_directions(11, np.radians(29.0))
    R = rotation_xyz(0.2, -0.3, 1.1)
    t = np.array([120.0, -40.0, 15.0])
    depth = rng.uniform(800.0, 1600.0, size=len(ids))  # any surface: the solve does not care
    points = t + (dirs * depth[:, None]) @ R.T
    keep = rng.permutation(len(ids))[:70]  # spots missing, any order
    result = opl.locate_source(pattern, points[keep], ids[keep])
    np.testing.assert_allclose(result.origin, t, atol=1e-6)
    np.testing.assert_allclose(result.scene_from_source.rotation, R, atol=1e-9)
    np.testing.assert_allclose(result.rotation_xyz_rad, [0.2, -0.3, 1.1], atol=1e-9)
    assert result.num_spots == 70 and result.num_inliers == 70
    # The Rigid3 maps source-frame points as x_scene = R x + t.
    np.testing.assert_allclose(result.scene_from_source.apply(dirs[:3] * 1000.0),
                               (dirs[:3] * 1000.0) @ R.T + t, atol=1e-6)


def test_locate_flags_a_wrong_spot():
    pattern = opl.make_equal_angle_pattern(11, np.radians(29.0))
    ids, dirs = equal_angle_directions(11, np.radians(29.0))
    points = dirs * 1000.0
    points[10] += [0.0, 30.0, 0.0]  # a reflection 30 mm off
    options = opl.LocateOptions()
    options.loss = opl.RobustLoss.CAUCHY
    result = opl.locate_source(pattern, points, ids, options=options)
    assert result.outlier_beam_ids() == [int(ids[10])]
    np.testing.assert_allclose(result.origin, [0, 0, 0], atol=1e-6)


def test_locate_errors_name_the_argument():
    pattern = opl.make_equal_angle_pattern(11, np.radians(29.0))
    with pytest.raises(opl.InvalidArgumentError, match=r"locate_source: points: expected an \(N, 3\)"):
        opl.locate_source(pattern, np.zeros((5, 2)), [1, 2, 3, 4, 5])
    with pytest.raises(ValueError, match="beam_ids: expected 3"):
        opl.locate_source(pattern, np.zeros((3, 3)), [1, 2])
    with pytest.raises(opl.Error):
        opl.locate_source(pattern, np.ones((2, 3)), [1, 2])  # too few spots


def test_simulated_scene_gives_the_truth(prototype_design):
    design = prototype_design
    design.spot_noise_mm = np.zeros(3)
    calibration = design.exact_calibration()
    options = opl.SpotSimulationOptions()
    options.attach_covariance = False
    spots, truth, outliers = opl.simulate_spots(design, options)
    assert len(spots) == 242 and not outliers.any()
    np.testing.assert_allclose(spots.points, truth, atol=1e-12)
    report = opl.measure_scale(calibration, spots)
    assert report.s == pytest.approx(1.0, abs=1e-9)
    origins = {name: r.origin for name, r in report.sources}
    np.testing.assert_allclose(origins["A"], [0.0, 27.5, 0.0], atol=1e-7)
    np.testing.assert_allclose(origins["B"], [0.0, -27.5, 0.0], atol=1e-7)


def test_scaled_scene_gives_its_scale_and_unsorted_spots_are_identified(prototype_design):
    """Points divided by 2.5 (a scene in other units): s = 2.5 within 4 u(s);
    the same spots shuffled and stripped of source and beam are identified back."""
    calibration = prototype_design.exact_calibration()
    spots, truth, _ = opl.simulate_spots(prototype_design)
    k = 2.5
    scaled = opl.Spots(spots.points / k, spots.sources, spots.beam_ids,
                       covariances=spots.covariances / k**2)
    report = opl.measure_scale(calibration, scaled)
    assert 0 < report.u_s < 0.01 * k
    assert abs(report.s - k) < 4 * report.u_s
    assert report.s == pytest.approx(calibration.separations[0].length_mm / report.scale.lengths[0].photo)

    order = np.random.default_rng(3).permutation(len(spots))
    unsorted = opl.Spots(spots.points[order] / k, covariances=spots.covariances[order] / k**2)
    # Two identical square grids side by side: symmetric, so identification
    # refuses to guess ...
    refused = opl.identify_spots(calibration, unsorted)
    assert [s.outcome for s in refused.sources] == [opl.IdentifyOutcome.AMBIGUOUS] * 2
    assert refused.num_assigned() == 0
    # ... until told roughly where each source is and how it is turned.
    options = opl.IdentifyOptions()
    options.expected_rotation = {"A": np.eye(3), "B": np.eye(3)}
    options.expected_origin = {"A": np.array([0.0, 27.5, 0.0]) / k, "B": np.array([0.0, -27.5, 0.0]) / k}
    options.expected_origin_tolerance = 10.0 / k
    ident = opl.identify_spots(calibration, unsorted, options)
    names = [s.name for s in calibration.sources]
    got = [names[i] if i >= 0 else "" for i in ident.source_index]
    assert got == [spots.sources[i] for i in order]
    np.testing.assert_array_equal(ident.beam_ids, spots.beam_ids[order])
    measure_options = opl.MeasureOptions()
    measure_options.identify = options
    report2 = opl.measure_scale(calibration, unsorted, measure_options)
    # Same spots, same s (to a small fraction of u(s): the identified path starts the
    # solves from the identification's poses and spot order differs).
    assert abs(report2.s - report.s) < 0.02 * report.u_s
    assert report2.identification is not None


def test_compute_scale_factor_closed_form(prototype_design):
    calibration = prototype_design.exact_calibration()
    cov = np.eye(3) * 0.01
    a = opl.LocatedOrigin("A", np.array([0.0, 0.0, 0.0]), cov)
    b = opl.LocatedOrigin("B", np.array([0.0, 50.0, 0.0]), cov)
    result = opl.compute_scale_factor(calibration, [a, b])
    assert result.scale_factor == pytest.approx(55.0 / 50.0, rel=1e-12)
    # u(L_photo) = sqrt(0.01 + 0.01) along the baseline; u(s) = s u(L) / L.
    assert result.u_scale_factor == pytest.approx(55.0 / 50.0 * np.sqrt(0.02) / 50.0, rel=1e-9)


def test_rigid3_angle_convention():
    """R = Rx(a) Ry(b) Rz(c) as docs/method states, against numpy."""
    pose = opl.Rigid3.from_xyz_angles(np.array([0.3, -0.2, 0.7]), np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(pose.rotation, rotation_xyz(0.3, -0.2, 0.7), atol=1e-15)
    np.testing.assert_allclose(pose.xyz_angles_rad, [0.3, -0.2, 0.7], atol=1e-12)
    np.testing.assert_allclose((pose * pose.inverse()).rotation, np.eye(3), atol=1e-15)
    w, x, y, z = pose.quaternion_wxyz
    again = opl.Rigid3.from_quaternion(np.array([w, x, y, z]), pose.translation)
    np.testing.assert_allclose(again.rotation, pose.rotation, atol=1e-15)
    with pytest.raises(opl.InvalidArgumentError, match="Rigid3: rotation: not a rotation matrix"):
        opl.Rigid3(np.diag([1.0, 1.0, -1.0]), np.zeros(3))
