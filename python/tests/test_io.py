"""OPL's file formats through Python: round trips, the C++ CLI reading what
Python wrote, and errors that name the file and the field."""
import json
import pathlib
import struct
import subprocess

import numpy as np
import pytest

import opl


def test_module_calibration_round_trip(examples, tmp_path):
    c = opl.read_module_calibration(str(examples / "prototype_calibration.json"))
    assert [s.name for s in c.sources] == ["A", "B"]
    path = tmp_path / "cal.json"
    opl.write_module_calibration(c, str(path))
    back = opl.read_module_calibration(str(path))
    for s, t in zip(c.sources, back.sources):
        np.testing.assert_array_equal(s.pattern.ids, t.pattern.ids)
        np.testing.assert_allclose(s.pattern.az_rad, t.pattern.az_rad, rtol=0, atol=0)
        np.testing.assert_allclose(s.calibration_from_source.translation,
                                   t.calibration_from_source.translation, rtol=0, atol=0)
    assert back.separations[0].length_mm == c.separations[0].length_mm
    # The separation is the distance between the two origins (independently).
    o = [s.calibration_from_source.translation for s in c.sources]
    assert np.linalg.norm(o[0] - o[1]) == pytest.approx(c.separations[0].length_mm, abs=1e-6)


def test_bad_calibration_names_file_and_field(examples, tmp_path):
    doc = json.loads((examples / "prototype_calibration.json").read_text())
    doc["sources"][0]["beams_per_side"] = "eleven"
    bad = tmp_path / "bad_calibration.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(opl.ParseError) as e:
        opl.read_module_calibration(str(bad))
    assert str(bad) in str(e.value) and "beams_per_side" in str(e.value)
    assert isinstance(e.value, ValueError)
    with pytest.raises(opl.IoError, match="no_such.json"):
        opl.read_module_calibration(str(tmp_path / "no_such.json"))
    with pytest.raises(OSError):
        opl.read_module_calibration(str(tmp_path / "no_such.json"))


def test_bad_spots_csv_names_file_line_and_field(tmp_path):
    bad = tmp_path / "spots.csv"
    bad.write_text("source,beam,x,y,z\nA,1,1,2,3\nA,2,1,abc,3\n")
    with pytest.raises(opl.ParseError) as e:
        opl.read_spots_csv(str(bad))
    assert f"{bad}:3" in str(e.value) and "'y'" in str(e.value)


def test_spots_written_by_python_give_the_same_s_in_opl_measure(prototype_design, tmp_path, apps_dir):
    calibration = prototype_design.exact_calibration()
    spots, _, _ = opl.simulate_spots(prototype_design)
    cal_path, spots_path = tmp_path / "cal.json", tmp_path / "spots.csv"
    opl.write_module_calibration(calibration, str(cal_path))
    opl.write_spots_csv(spots, str(spots_path))
    back = opl.read_spots_csv(str(spots_path))
    np.testing.assert_array_equal(back.points, spots.points)  # shortest round-trip text
    assert back.sources == spots.sources
    np.testing.assert_array_equal(back.beam_ids, spots.beam_ids)
    np.testing.assert_allclose(back.covariances, spots.covariances, rtol=1e-15)

    out = subprocess.run([str(apps_dir / "opl_measure"), "--calibration", str(cal_path),
                          "--spots", str(spots_path), "--json"],
                         check=True, capture_output=True, text=True).stdout
    cli = json.loads(out)
    report = opl.measure_scale(calibration, spots)
    assert cli["scale_factor"] == pytest.approx(report.s, rel=1e-12)
    assert cli["u_scale_factor"] == pytest.approx(report.u_s, rel=1e-9)
    assert json.loads(report.to_json())["scale_factor"] == pytest.approx(report.s, rel=1e-15)


def test_point_table_and_points_csv(tmp_path):
    table = tmp_path / "targets.txt"
    table.write_text("# from another program\nP1 1.5 2.5 3.5\nP2 -1 0 4e2\n")
    spots = opl.read_point_table(str(table), "id,x,y,z", delimiter="whitespace")
    np.testing.assert_array_equal(spots.points, [[1.5, 2.5, 3.5], [-1, 0, 400]])
    assert not spots.assigned.any()

    csv = tmp_path / "points.csv"
    csv.write_text("id,x,y,z,label\np1,1,2,3,wall\np2,0.5,-1,2,floor\n")
    points = opl.PointsCsv.read(str(csv))
    assert points.ids == ["p1", "p2"] and len(points) == 2
    points.scale(2.0)
    np.testing.assert_array_equal(points.points, [[2, 4, 6], [1, -2, 4]])
    out = tmp_path / "scaled.csv"
    points.write(str(out))
    assert "floor" in out.read_text()
    np.testing.assert_array_equal(opl.PointsCsv.read(str(out)).points, [[2, 4, 6], [1, -2, 4]])
    with pytest.raises(opl.InvalidArgumentError):
        points.scale(-1.0)


def test_scale_point_file_ply_keeps_other_properties(tmp_path):
    xyz = np.array([[1.0, 2.0, 3.0], [-4.5, 0.25, 8.0]])
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 2\n"
              "property double x\nproperty double y\nproperty double z\n"
              "property uchar red\nend_header\n").encode()
    body = b"".join(struct.pack("<dddB", *p, 200 + i) for i, p in enumerate(xyz))
    src, dst = tmp_path / "cloud.ply", tmp_path / "cloud_mm.ply"
    src.write_bytes(header + body)
    summary = opl.scale_point_file(str(src), str(dst), 3.0)
    assert summary.num_points == 2 and summary.format == opl.PointFileFormat.PLY
    out_header, body_out = dst.read_bytes().split(b"end_header\n", 1)
    assert b"property uchar red" in out_header and b"s = 3" in out_header  # says what was done
    rec = np.frombuffer(body_out, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1")])
    np.testing.assert_array_equal(np.stack([rec["x"], rec["y"], rec["z"]], 1), 3.0 * xyz)
    np.testing.assert_array_equal(rec["red"], [200, 201])

    xyz_file = tmp_path / "cloud.xyz"
    xyz_file.write_text("1 2 3\n4 5 6\n")
    opl.scale_point_file(str(xyz_file), str(tmp_path / "out.xyz"), 0.5)
    np.testing.assert_array_equal(np.loadtxt(tmp_path / "out.xyz"), [[0.5, 1, 1.5], [2, 2.5, 3]])

    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
    with pytest.raises(opl.Error, match="bad.ply"):
        opl.scale_point_file(str(bad), str(tmp_path / "never.ply"), 2.0)
    assert not (tmp_path / "never.ply").exists()


def test_spots_at_two_placements(prototype_design, examples, tmp_path, apps_dir):
    """The module at two placements (docs/multiview.md): the placement column
    round-trips, and each source is located at each placement, in Python as
    in opl_measure. (The design's ideal grids are symmetric, so the spots
    keep their source and beam: measure_test covers the identification.)"""
    calibration = prototype_design.exact_calibration()
    first, _, _ = opl.simulate_spots(prototype_design)
    moved = first.points + np.array([0.0, 250.0, 80.0])  # the module (and its wall) 250 mm aside
    n = len(first)
    spots = opl.Spots(np.vstack([first.points, moved]), sources=first.sources * 2,
                      beam_ids=np.concatenate([first.beam_ids, first.beam_ids]),
                      sigmas=np.full((2 * n, 3), 0.05), placements=["here"] * n + ["there"] * n)
    assert spots.placements[0] == "here" and spots.placements[-1] == "there"
    path = tmp_path / "spots.csv"
    opl.write_spots_csv(spots, str(path))
    assert path.read_text().splitlines()[0] == "source,beam,x,y,z,sx,sy,sz,placement"
    back = opl.read_spots_csv(str(path))
    assert back.placements == spots.placements
    report = opl.measure_scale(calibration, back)
    assert report.source_placements == ["here"] * 2 + ["there"] * 2
    assert [l.placement for l in report.scale.lengths] == ["here", "there"]
    assert report.s == pytest.approx(1.0, abs=5 * report.u_s)
    cal_path = tmp_path / "cal.json"
    opl.write_module_calibration(calibration, str(cal_path))
    out = subprocess.run([str(apps_dir / "opl_measure"), "--calibration", str(cal_path),
                          "--spots", str(path), "--json"], check=True, capture_output=True, text=True).stdout
    cli = json.loads(out)
    assert cli["scale_factor"] == pytest.approx(report.s, rel=1e-12)
    assert [l["placement"] for l in cli["lengths"]] == ["here", "there"]
    scene = opl.Scene.read(str(examples / "scene_small_placements.json"))
    assert scene.module_placements == ["centre", "aside"]
    assert scene.shots[0].placement == "centre" and scene.shots[-1].placement in ("aside", "")


def test_cameras_and_scene(examples, tmp_path):
    scene = opl.Scene.read(str(examples / "scene_small.json"))
    assert len(scene.cameras) >= 1 and len(scene.shots) >= 1
    cam = scene.cameras[0]
    assert cam.intrinsics.width_px > 0 and cam.intrinsics.fx_px > 0
    path = tmp_path / "cameras.json"
    opl.write_cameras(scene.cameras, str(path))
    back = opl.read_cameras(str(path))
    assert [c.name for c in back] == [c.name for c in scene.cameras]
    assert back[0].intrinsics.fx_px == cam.intrinsics.fx_px
    assert back[0].intrinsics.k1 == cam.intrinsics.k1
    # The projection of a point on the optical axis is the principal point.
    px = cam.intrinsics.project(np.array([0.0, 0.0, 1000.0]))
    np.testing.assert_allclose(px, [cam.intrinsics.cx_px, cam.intrinsics.cy_px], atol=1e-9)
    assert cam.intrinsics.project(np.array([0.0, 0.0, -1.0])) is None

    doc = json.loads((examples / "scene_small.json").read_text())
    doc["cameras"][0]["fx_px"] = -5
    bad = tmp_path / "bad_scene.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(opl.Error) as e:
        opl.Scene.read(str(bad))
    assert "bad_scene.json" in str(e.value)


def test_design_json_errors_name_the_field(examples, tmp_path):
    doc = json.loads((examples / "prototype_design.json").read_text())
    doc["sources"][1]["full_angle_deg"] = 0
    bad = tmp_path / "design.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(opl.Error) as e:
        opl.ModuleDesign.read(str(bad))
    assert "design.json" in str(e.value) and "sources[1].full_angle_deg" in str(e.value)


def test_point_cloud_read_write_round_trip(tmp_path):
    rng = np.random.default_rng(5)
    points = rng.normal(size=(50, 3)) * 1234.5
    for name, binary in [("c.ply", True), ("a.ply", False), ("c.xyz", True), ("c.csv", True)]:
        path = tmp_path / name
        opl.write_point_cloud(points, str(path), binary=binary)
        np.testing.assert_array_equal(opl.read_point_cloud(str(path)), points)  # exact: shortest text
    assert b"format ascii" in (tmp_path / "a.ply").read_bytes()[:40]
    # The written PLY is what scale_point_file streams: scaled, read back.
    opl.scale_point_file(str(tmp_path / "c.ply"), str(tmp_path / "s.ply"), 2.0)
    np.testing.assert_allclose(opl.read_point_cloud(str(tmp_path / "s.ply")), 2.0 * points, rtol=1e-15)


def test_read_ply_with_other_properties_and_faces(tmp_path):
    """A mesh as a scanner writes it (written with struct here, independently):
    float x, y, z among other properties, a face element after the vertices."""
    xyz = np.array([[1.5, -2.0, 3.25], [4.0, 5.5, -6.0], [0.0, 0.125, 8.0]], dtype=np.float32)
    header = ("ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty uchar flag\n"
              "property float x\nproperty float y\nproperty float z\nproperty list uchar int idx\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = b"".join(struct.pack(">Bfff", 7, *p) + struct.pack(">Bi", 1, i) for i, p in enumerate(xyz))
    body += struct.pack(">Biii", 3, 0, 1, 2)
    path = tmp_path / "mesh.ply"
    path.write_bytes(header + body)
    np.testing.assert_array_equal(opl.read_point_cloud(str(path)), xyz.astype(float))
    path.write_bytes(header + body[:20])
    with pytest.raises(opl.ParseError, match="mesh.ply.*cut off"):
        opl.read_point_cloud(str(path))
    ascii_ply = tmp_path / "ascii.ply"
    ascii_ply.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                         "property float z\nproperty uchar red\nend_header\n1 2 3 255\n4 5 abc 0\n")
    with pytest.raises(opl.ParseError) as e:
        opl.read_point_cloud(str(ascii_ply))
    assert "ascii.ply" in str(e.value) and "'z'" in str(e.value)
    xyz_file = tmp_path / "bad.xyz"
    xyz_file.write_text("1 2 3\n# comment\n4 x 6\n")
    with pytest.raises(opl.ParseError, match=r"bad.xyz:3: field 'y'"):
        opl.read_point_cloud(str(xyz_file))


def test_design_written_from_python_drives_opl_simulate(prototype_design, tmp_path, apps_dir):
    """A design changed in Python and written is read by the C++ tool: the
    spots opl_simulate throws from it sit where the moved source's beams
    land (the central beam of the moved source hits the 1 m screen at y =
    the new origin's y, z = 0: a closed form, not the writer's text)."""
    design = prototype_design
    sources = design.sources
    origin = np.array(sources[1].scene_from_source.translation)
    origin[1] = -40.0
    pose = sources[1].scene_from_source
    pose.translation = origin
    sources[1].scene_from_source = pose
    design.sources = sources
    noise_free = design
    noise_free.spot_noise_mm = np.zeros(3)
    path = tmp_path / "moved_design.json"
    noise_free.write(str(path), "moved by the test")
    doc = json.loads(path.read_text())
    assert doc["format"] == "opl.module_design" and doc["description"] == "moved by the test"
    assert doc["sources"][1]["origin_mm"] == [0.0, -40.0, 0.0]
    again = opl.ModuleDesign.read(str(path))
    assert np.allclose(again.sources[1].scene_from_source.translation, origin, atol=0)
    out = tmp_path / "spots.csv"
    subprocess.run([str(apps_dir / "opl_simulate"), "spots", "--design", str(path), "--out", str(out)],
                   check=True, capture_output=True)
    rows = [l.split(",") for l in out.read_text().splitlines() if l and not l.startswith("#")]
    header = rows[0]
    col = {name: header.index(name) for name in ("source", "beam", "x", "y", "z")}
    n = doc["sources"][1]["beams_per_side"]
    central = (n * n + 1) // 2
    hit = [r for r in rows[1:] if r[col["source"]] == "B" and int(r[col["beam"]]) == central]
    assert len(hit) == 1
    x, y, z = (float(hit[0][col[k]]) for k in ("x", "y", "z"))
    assert abs(x - 1000.0) < 1e-9 and abs(y + 40.0) < 1e-9 and abs(z) < 1e-9
