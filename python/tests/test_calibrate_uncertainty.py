"""calibrate_module on simulated calibration sessions, and the Monte Carlo
studies (measurement, calibration, design sweep) checked against their
first-order predictions, numpy and the expected scaling laws."""
import json

import numpy as np
import pytest

import opl


def session(design, depths=(750.0, 900.0, 1050.0, 1200.0, 1350.0)):
    options = opl.ScreenSlicesOptions()
    options.depths_mm = list(depths)
    simulation = opl.SpotSimulationOptions()
    simulation.attach_covariance = bool(np.any(design.spot_noise_mm > 0))  # zero noise: unweighted
    return opl.simulate_slices(design, opl.make_calibration_screens(design, options), simulation)


def test_noise_free_session_calibrates_to_the_design(prototype_design):
    design = prototype_design
    design.spot_noise_mm = np.zeros(3)
    spots, truth, _ = session(design)
    assert len(spots) == 2 * 121 * 5
    assert sorted(set(spots.slices)) == list(range(10))  # one grid per slice: source i, screen k -> 5 i + k
    result = opl.calibrate_module(spots)
    calibration = result.calibration
    assert calibration.separations[0].length_mm == pytest.approx(55.0, abs=1e-6)
    exact = design.exact_calibration()
    for got, want in zip(calibration.sources, exact.sources):
        np.testing.assert_allclose(got.calibration_from_source.translation,
                                   want.calibration_from_source.translation, atol=1e-6)
        np.testing.assert_array_equal(got.pattern.ids, want.pattern.ids)
        np.testing.assert_allclose(got.pattern.directions, want.pattern.directions, atol=1e-9)
    # A calibration that came from Python writes and reads back as any other.
    text = opl.format_module_calibration(calibration)
    back = opl.parse_module_calibration(text, "calibrated")
    assert back.separations[0].length_mm == calibration.separations[0].length_mm


def test_noisy_session_separation_within_its_uncertainty(prototype_design):
    spots, _, _ = session(prototype_design)
    result = opl.calibrate_module(spots)
    sep = result.calibration.separations[0]
    assert 0.005 < sep.u_length_mm < 0.1
    assert abs(sep.length_mm - 55.0) < 4 * sep.u_length_mm
    quality = result.calibration.sources[0].quality
    assert quality is not None and quality.samples_used > 500
    # Mean point-to-ray distance is of the order of the spot noise (0.07-0.11 mm).
    assert 0.02 < quality.mean_point_to_ray_mm < 0.2


def test_calibrate_refuses_two_grids_in_one_slice(prototype_design):
    spots, _, _ = opl.simulate_spots(prototype_design)  # both grids, slice 0
    with pytest.raises(opl.InvalidArgumentError, match="slice 0 holds spots of source"):
        opl.calibrate_module(spots)


def test_measurement_monte_carlo(prototype_design):
    options = opl.MonteCarloOptions()
    options.iterations = 300
    options.threads = 2
    report = opl.run_measurement_monte_carlo(prototype_design, options)
    assert report.succeeded == 300 and report.failed == 0
    length = report.lengths[0]
    samples = length.samples_mm
    assert len(samples) == 300
    # The summary is the samples' own statistics (numpy, independently).
    assert length.photo_mm.mean == pytest.approx(np.mean(samples), rel=1e-12)
    assert length.photo_mm.std_dev == pytest.approx(np.std(samples, ddof=1), rel=1e-9)
    assert report.scale_factor.std_dev == pytest.approx(np.std(report.scale_samples, ddof=1), rel=1e-9)
    # s = L_cal / L_photo sample by sample.
    np.testing.assert_allclose(report.scale_samples, 55.0 / samples, rtol=1e-12)
    # The spread agrees with the first-order prediction (300 samples: std of
    # the std about 4 %), and the true length lies in the 95 % interval.
    assert length.photo_mm.std_dev == pytest.approx(length.photo_mm.first_order_std, rel=0.15)
    assert length.photo_mm.symmetric.low < 55.0 < length.photo_mm.symmetric.high
    # The JSON carries the samples only when asked for, exactly.
    assert "sample_iterations" not in json.loads(report.to_json())
    full = json.loads(report.to_json(include_samples=True))
    assert full["sample_iterations"] == list(report.sample_iterations) == list(range(300))
    assert full["lengths"][0]["samples_mm"] == list(samples)


def test_design_sweep_is_linear_in_noise(prototype_design):
    options = opl.MonteCarloOptions()
    options.iterations = 200
    sweep = opl.run_design_sweep(prototype_design, opl.SweepParameter.NOISE_MM, [0.05, 0.1, 0.2], options)
    std = np.array([p.report.lengths[0].photo_mm.std_dev for p in sweep.points])
    # Same seed, noise scaled: the spread scales with it (method.md: linear in spot noise).
    np.testing.assert_allclose(std / std[0], [1.0, 2.0, 4.0], rtol=0.01)
    assert sweep.to_csv().startswith("parameter,value,")
    more_beams = opl.apply_sweep_value(prototype_design, opl.SweepParameter.BEAMS_PER_SIDE, 15)
    assert [s.beams_per_side for s in more_beams.sources] == [15, 15]


def test_calibration_monte_carlo(prototype_design):
    options = opl.CalibrationMonteCarloOptions()
    options.iterations = 60
    options.threads = 2
    report = opl.run_calibration_monte_carlo(prototype_design, options)
    assert report.succeeded == 60
    length = report.lengths[0]
    assert length.true_mm == pytest.approx(55.0, abs=1e-9)
    assert length.length_mm.std_dev == pytest.approx(np.std(length.samples_mm, ddof=1), rel=1e-9)
    assert length.length_mm.std_dev == pytest.approx(length.length_mm.first_order_std, rel=0.3)


def test_options_are_checked(prototype_design):
    options = opl.MonteCarloOptions()
    options.iterations = 0
    with pytest.raises(opl.InvalidArgumentError, match="iterations"):
        opl.run_measurement_monte_carlo(prototype_design, options)
