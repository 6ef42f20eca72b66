"""COLMAP models and the images front end through Python."""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import opl
from conftest import rotation_xyz


def quaternion_wxyz(R):
    """Unit quaternion of a rotation matrix (numpy, trace > 0 case)."""
    w = np.sqrt(1.0 + np.trace(R)) / 2.0
    return np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])


def write_text_model(folder):
    """A two-image COLMAP text model with three points seen in both; returns
    the points and the camera centres."""
    folder.mkdir()
    points = np.array([[0.1, 0.2, 5.0], [-0.5, 0.3, 6.0], [0.4, -0.6, 4.5]])
    poses = [(rotation_xyz(0.05, -0.1, 0.02), np.array([0.2, -0.1, 0.3])),
             (rotation_xyz(-0.04, 0.12, 0.0), np.array([-0.5, 0.0, 0.1]))]
    f, cx, cy = 500.0, 320.0, 240.0
    (folder / "cameras.txt").write_text(f"# cameras\n1 PINHOLE 640 480 {f} {f} {cx} {cy}\n")
    lines, centres = [], []
    for i, (R, t) in enumerate(poses, start=1):
        q = quaternion_wxyz(R)
        lines.append(f"{i} {q[0]!r} {q[1]!r} {q[2]!r} {q[3]!r} {t[0]!r} {t[1]!r} {t[2]!r} 1 img{i}.png")
        obs = []
        for k, p in enumerate(points, start=1):
            pc = R @ p + t
            obs.append(f"{f * pc[0] / pc[2] + cx!r} {f * pc[1] / pc[2] + cy!r} {k}")
        lines.append(" ".join(obs))
        centres.append(-R.T @ t)
    (folder / "images.txt").write_text("# images\n" + "\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("# points\n" + "".join(
        f"{k} {p[0]!r} {p[1]!r} {p[2]!r} 10 20 30 0.5 1 {k - 1} 2 {k - 1}\n" for k, p in enumerate(points, start=1)))
    return points, np.array(centres)


def test_colmap_model_read_scale_write(tmp_path):
    points, centres = write_text_model(tmp_path / "sparse")
    model = opl.ColmapModel.read(str(tmp_path / "sparse"))
    assert model.format == opl.ColmapFormat.TEXT
    np.testing.assert_allclose(model.points3d, points, rtol=1e-15)
    assert model.point3d_ids == [1, 2, 3]
    np.testing.assert_array_equal(model.colors, [[10, 20, 30]] * 3)
    np.testing.assert_allclose(model.images[1].center_in_world(), centres[0], atol=1e-12)
    intrinsics = model.cameras[1].intrinsics()
    # OPL's pixel convention is COLMAP's minus 0.5.
    assert (intrinsics.fx_px, intrinsics.cx_px) == (500.0, 319.5)

    scaled = model.scaled(2.5)
    scaled.write(str(tmp_path / "out"), opl.ColmapFormat.BINARY)
    back = opl.ColmapModel.read(str(tmp_path / "out"))
    assert back.format == opl.ColmapFormat.BINARY
    np.testing.assert_allclose(back.points3d, 2.5 * points, rtol=1e-12)
    for i in (1, 2):
        np.testing.assert_allclose(back.images[i].center_in_world(), 2.5 * centres[i - 1], atol=1e-12)
        np.testing.assert_allclose(back.images[i].points2d_px, model.images[i].points2d_px, rtol=0)
    colmap = shutil.which("colmap")
    if colmap:  # COLMAP itself reads what Python wrote (.ci/deps installs it)
        out = subprocess.run([colmap, "model_analyzer", "--path", str(tmp_path / "out")],
                             capture_output=True, text=True, env=dict(os.environ, QT_QPA_PLATFORM="offscreen"))
        assert out.returncode == 0, out.stderr
        assert "Points: 3" in out.stdout + out.stderr


def test_bad_colmap_model_names_the_file(tmp_path):
    write_text_model(tmp_path / "sparse")
    (tmp_path / "sparse" / "cameras.txt").write_text("1 PINHOLE 640 480 500 500 320\n")
    with pytest.raises(opl.ParseError) as e:
        opl.ColmapModel.read(str(tmp_path / "sparse"))
    assert "cameras.txt" in str(e.value)


def test_scale_from_rendered_images(examples, apps_dir, tmp_path):
    """The virtual lab renders the small scene (C++ CLI); Python measures it.
    s agrees with the scale of the measured spots to their true positions
    (a similarity fitted in numpy), and with opl_measure on the same images."""
    images = tmp_path / "images"
    subprocess.run([str(apps_dir / "opl_simulate"), "images", "--scene", str(examples / "scene_small.json"),
                    "--out", str(images), "--threads", "2"], check=True, capture_output=True)
    scene = opl.Scene.read(str(examples / "scene_small.json"))
    calibration = scene.module.exact_calibration()
    options = opl.ImageMeasureOptions()
    options.front_end.num_threads = 2
    report = opl.measure_scale_from_images(scene, str(images), calibration, options)
    assert 0.002 < report.two_step_u_s < 0.05
    # The reported s is the scale inside the adjustment, 5 times more precise or better.
    assert report.scale_method == "adjustment" and report.scale_method_note == ""
    assert 0 < 5 * report.u_s < report.two_step_u_s
    spots = report.spots
    assert len(spots) > 200 and spots.assigned.all()

    truth = json.loads((images / "truth.json").read_text())
    true_points = {(s["source"], s["beam"]): np.array(s["point_mm"]) for s in truth["spots"]}
    P = spots.points
    T = np.array([true_points[(a, int(b))] for a, b in zip(spots.sources, spots.beam_ids)])
    X, Y = P - P.mean(0), T - T.mean(0)
    U, S, Vt = np.linalg.svd(Y.T @ X)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    s_truth = np.trace(np.diag(S) @ D) / np.sum(X**2)  # Umeyama's scale, mm per scene unit
    residual = Y - s_truth * X @ (U @ D @ Vt).T
    assert np.sqrt(np.mean(np.sum(residual**2, 1))) < 1.0  # spots placed to under a mm
    assert abs(report.s - s_truth) < 3 * report.u_s
    assert abs(report.two_step_s - s_truth) < 3 * report.two_step_u_s

    cal_path = tmp_path / "cal.json"
    opl.write_module_calibration(calibration, str(cal_path))
    out = subprocess.run([str(apps_dir / "opl_measure"), "--calibration", str(cal_path), "--images", str(images),
                          "--scene", str(examples / "scene_small.json"), "--threads", "2", "--json"],
                         check=True, capture_output=True, text=True).stdout
    cli = json.loads(out)
    assert cli["scale_method"] == "adjustment"
    assert cli["scale_factor"] == pytest.approx(report.s, rel=1e-9)
    assert cli["u_scale_factor"] == pytest.approx(report.u_s, rel=1e-6)
    assert cli["measure"]["scale_factor"] == pytest.approx(report.two_step_s, rel=1e-9)
    assert cli["measure"]["u_scale_factor"] == pytest.approx(report.two_step_u_s, rel=1e-9)
    assert json.loads(report.to_json())["scale_factor"] == pytest.approx(report.s, rel=1e-15)


def test_missing_image_names_the_file(examples, tmp_path):
    scene = opl.Scene.read(str(examples / "scene_small.json"))
    calibration = scene.module.exact_calibration()
    with pytest.raises(opl.Error, match="cam0_A.png"):
        opl.measure_scale_from_images(scene, str(tmp_path), calibration)
