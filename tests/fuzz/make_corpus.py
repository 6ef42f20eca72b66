#!/usr/bin/python3
"""Writes the text seeds of tests/fuzz/corpus/ (issue 19 item 10).

Run from the top of the checkout after a build:
  /usr/bin/python3 tests/fuzz/make_corpus.py build
It simulates a small module (5 x 5 beams, tests/fuzz/corpus/design_json/
tiny.json) with the built tools, cuts the examples small, and writes every
hostile input of issue 19's findings (items 1-7) beside them. The image
seeds (png/, jpeg/) are small pictures written with Pillow (python3-pil),
and the 60-byte PNG whose header claims 100000 x 100000 pixels. The files are
committed; this script documents where each came from and remakes them.
"""
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")
EXAMPLES = os.path.join(ROOT, "examples")
BUILD = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build")
APPS = os.path.join(BUILD if os.path.isabs(BUILD) else os.path.join(ROOT, BUILD), "apps")

TINY_DESIGN = {
    "format": "opl.module_design",
    "version": 1,
    "description": "Fuzz corpus: two 5 x 5 equal-angle sources, 29 deg, 55 mm apart, a screen 1 m ahead.",
    "sources": [
        {"name": "A", "pattern": "equal_angle", "beams_per_side": 5, "full_angle_deg": 29.0,
         "origin_mm": [0.0, 27.5, 0.0], "rotation_xyz_rad": [0.0, 0.0, 0.0]},
        {"name": "B", "pattern": "equal_angle", "beams_per_side": 5, "full_angle_deg": 29.0,
         "origin_mm": [0.0, -27.5, 0.0], "rotation_xyz_rad": [0.0, 0.0, 0.0],
         "beam_error_mrad": 0.3, "beam_error_seed": 8},
    ],
    "surface": {"type": "plane", "point_mm": [1000.0, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]},
    "spot_noise_mm": [0.110, 0.073, 0.073],
}


def write(fmt, name, data):
    folder = os.path.join(CORPUS, fmt)
    os.makedirs(os.path.dirname(os.path.join(folder, name)), exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(os.path.join(folder, name), mode, newline="" if mode == "w" else None) as f:
        f.write(data)


def read(path):
    with open(path) as f:
        return f.read()


def run(*args):
    subprocess.run([os.path.join(APPS, args[0])] + list(args[1:]), check=True,
                   stdout=subprocess.DEVNULL)


def no_provenance(text):
    return "".join(line for line in text.splitlines(True) if not line.startswith("# opl "))


def keep_columns(csv, names):
    lines = csv.splitlines()
    header = lines[0].split(",")
    idx = [header.index(n) for n in names]
    return "".join(",".join(line.split(",")[i] for i in idx) + "\n" for line in lines if line)


def set_field(csv, line, column, value):
    lines = csv.split("\n")
    fields = lines[line - 1].split(",")
    fields[column] = value
    lines[line - 1] = ",".join(fields)
    return "\n".join(lines)


def scaled(csv, factor, columns=("x", "y", "z", "sx", "sy", "sz")):
    lines = csv.splitlines()
    header = lines[0].split(",")
    idx = [header.index(c) for c in columns if c in header]
    out = [lines[0]]
    for line in lines[1:]:
        f = line.split(",")
        for i in idx:
            f[i] = repr(float(f[i]) * factor)
        out.append(",".join(f))
    return "\n".join(out) + "\n"


def deep_json():
    # issue 19 item 1: 80 KB of '[' took 2.4 GB in the JSON readers.
    return "{\n\"a\": " + "[" * 80000


def main():
    tmp = tempfile.mkdtemp()
    design_path = os.path.join(tmp, "tiny.json")
    with open(design_path, "w") as f:
        json.dump(TINY_DESIGN, f, indent=2)
    cal = os.path.join(tmp, "cal.json")
    run("opl_simulate", "calibration", "--design", design_path, "--out", cal)
    run("opl_simulate", "spots", "--design", design_path, "--out", os.path.join(tmp, "spots.csv"),
        "--seed", "3", "--missing", "0.1", "--outliers", "0.04")
    run("opl_simulate", "slices", "--design", design_path, "--depths", "800:200:1200",
        "--out", os.path.join(tmp, "slices.csv"), "--seed", "5")
    slices_raw = read(os.path.join(tmp, "slices.csv"))
    run("opl_calibrate", "--spots", os.path.join(tmp, "slices.csv"), "--out",
        os.path.join(tmp, "calibrated.json"))

    # Files are overwritten, not removed first: the corpus also holds the
    # fuzzer's own findings (found_*, copied from a findings folder).
    spots_raw = read(os.path.join(tmp, "spots.csv"))
    spots = keep_columns(no_provenance(spots_raw), ["source", "beam", "x", "y", "z", "sx", "sy", "sz"])
    slices = keep_columns(no_provenance(slices_raw),
                          ["source", "beam", "x", "y", "z", "sx", "sy", "sz", "slice"])

    # --- spots CSV (opl_measure --spots)
    write("spots_csv", "tiny.csv", spots)
    write("spots_csv", "tiny_with_provenance.csv", spots_raw)
    write("spots_csv", "unassigned.csv", "source,beam,x,y,z\n" + "".join(
        ",," + ",".join(l.split(",")[2:5]) + "\n" for l in spots.splitlines()[1:12]))
    write("spots_csv", "placements_quoted_crlf_bom.csv", "\ufeff" + "\r\n".join(
        ["placement,\"source\",beam,x,y,z"] +
        ["\"p 1\"," + l.split(",")[0] + "," + ",".join(l.split(",")[1:5]) for l in spots.splitlines()[1:8]]) + "\r\n")
    # issue 19 item 6: numbers beyond their range; item 4: units (x 1000, x 1e-9).
    write("spots_csv", "x_1e308.csv", set_field(spots, 2, 2, "1e308"))
    write("spots_csv", "sigma_1e-300.csv", set_field(spots, 2, 5, "1e-300"))
    write("spots_csv", "nan_inf.csv", set_field(set_field(spots, 3, 3, "nan"), 4, 4, "-inf"))
    write("spots_csv", "scaled_1000.csv", scaled(spots, 1000.0))
    write("spots_csv", "scaled_1e-9.csv", scaled(spots, 1e-9))
    # item 7: control characters and long fields echoed.
    write("spots_csv", "ansi_escape.csv", set_field(spots, 2, 0, "\x1b[2J\x1b[31mA"))
    write("spots_csv", "newline_in_quotes.csv", set_field(spots, 2, 0, "\"A\nB\r\""))
    write("spots_csv", "long_field.csv", set_field(spots, 2, 0, "Q" * 5000))
    write("spots_csv", "bell_in_number.csv", set_field(spots, 2, 2, "1\x07" + "2" * 100))
    # item 1: a wide header (the duplicate check was quadratic: 16k columns 4.2 s).
    write("spots_csv", "wide_header.csv", "source,beam,x,y,z" + "".join(
        ",c%d" % i for i in range(16384)) + ",x\nA,1,1,2,3\n")
    write("spots_csv", "duplicate_spot.csv", spots + spots.splitlines()[1] + "\n")

    # --- slices CSV (opl_calibrate --spots)
    write("slices_csv", "tiny_session.csv", slices)
    write("slices_csv", "tiny_session_raw.csv", slices_raw)
    write("slices_csv", "beam_2147483647.csv", slices.replace("\nA,1,", "\nA,2147483647,", 1))
    write("slices_csv", "y_1e300.csv", set_field(slices, 5, 3, "1e300"))
    write("slices_csv", "scaled_300.csv", scaled(slices, 300.0))
    write("slices_csv", "slice_negative.csv", set_field(slices, 3, 8, "-1"))

    # --- point tables from other software (--columns)
    write("point_table", "unsorted_head.txt", "".join(read(os.path.join(EXAMPLES, "unsorted_points.txt")).splitlines(True)[:24]))
    write("point_table", "semicolon_decimal_comma.csv", "# export\nid;x;y;z\nP1;12,5;3,25;1\nP2;1;2;3\n")
    write("point_table", "comma_slices.csv", "# exported\nhdr\n" + "".join(
        l + ",extra\n" for l in keep_columns(slices, ["source", "beam", "x", "y", "z", "slice"]).splitlines()[1:12]))
    write("point_table", "whitespace.txt", "name x y z\nP1  1012.5\t3.25 -0.5\n\"P 2\" 1 2 3\n")

    # --- points CSV (opl_measure --apply ... .csv)
    write("points_csv", "targets.csv", "name,x,y,z,flags\nT1,102.5,33.0,-4.25,ok\n\"T,2\",1,2,3,\"a \"\"b\"\"\"\n")
    write("points_csv", "id_1e308.csv", "id,x,y,z\np1,1,2,3\np2,1,2,1e308\n")
    write("points_csv", "crlf_bom_blank.csv", "\ufeffX,Y,Z,id\r\n1,2,3,a\r\n\r\n4,5,6,b\r\n")

    # --- point files streamed by --apply: PLY (ascii, binary), XYZ, CSV
    write("point_file", "ascii.ply", "ply\nformat ascii 1.0\ncomment fuzz\nelement vertex 3\n"
          "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
          "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
          "1 2 3 255\n4.5 5 6 0\n-7 8e2 9 12\n3 0 1 2\n")
    body = b"".join(struct.pack("<dddB", x, x + 1, x + 2, 7) for x in (1.0, 2.5, -3.0))
    write("point_file", "binary_le.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
          b"property double x\nproperty double y\nproperty double z\nproperty uchar flag\nend_header\n" + body)
    body = b"".join(struct.pack(">fff", x, -x, 2 * x) for x in (1.0, 2.5))
    write("point_file", "binary_be.ply", b"ply\nformat binary_big_endian 1.0\nelement vertex 2\n"
          b"property float32 x\nproperty float32 y\nproperty float32 z\nend_header\n" + body)
    write("point_file", "cloud.xyz", "# x y z r g b\n1 2 3 255 0 0\n4.5 -5 6e1 0 255 0\n\n7 8 9\n")
    write("point_file", "table.csv", "name,x,y,z\nT1,1,2,3\nT2,4,5,6\n")

    # --- module calibration JSON (--calibration)
    cal_text = read(cal)
    write("calibration_json", "tiny_exact.json", cal_text)
    write("calibration_json", "tiny_calibrated.json", read(os.path.join(tmp, "calibrated.json")))
    for n in ("203", "46341", "100001"):  # item 1: n^2 memory and int overflow
        write("calibration_json", "beams_per_side_%s.json" % n,
              cal_text.replace("\"beams_per_side\": 5", "\"beams_per_side\": " + n, 1))
    write("calibration_json", "deep_nesting.json", deep_json())
    c = json.loads(cal_text)  # item 5: A-B twice, 55 and 66 mm
    twice = dict(c["separations"][0])
    twice["length_mm"] = 66.0
    c["separations"].append(twice)
    write("calibration_json", "separation_twice.json", json.dumps(c))

    # --- module design JSON (opl_simulate --design)
    write("design_json", "tiny.json", json.dumps(TINY_DESIGN, indent=2))
    for name in ("prototype_design.json", "staggered_design.json", "anisotropic_design.json",
                 "fabricated_design.json"):
        write("design_json", name, read(os.path.join(EXAMPLES, name)))
    for n in ("203", "46341", "100001"):
        d = json.loads(json.dumps(TINY_DESIGN))
        d["sources"][0]["beams_per_side"] = int(n)
        write("design_json", "beams_per_side_%s.json" % n, json.dumps(d, indent=2))
    write("design_json", "deep_nesting.json", deep_json())
    pattern = "# beams_per_side: 3\n# a comment\nid,az_rad,el_rad\n" + "".join(
        "%d,%r,%r\n" % (i + 1, (i % 3 - 1) * 0.1, (1 - i // 3) * 0.1) for i in range(9))
    write("design_json", "aux/pattern3.csv", pattern)
    for name, path in (("file_pattern.json", "aux/pattern3.csv"),
                       ("pattern_dev_zero.json", "/dev/zero")):  # item 1: read forever
        d = json.loads(json.dumps(TINY_DESIGN))
        s = d["sources"][1]
        for k in ("beams_per_side", "full_angle_deg"):
            del s[k]
        s["pattern"] = "file"
        s["pattern_file"] = path
        write("design_json", name, json.dumps(d, indent=2))

    # --- pattern CSV (a design's pattern_file)
    write("pattern_csv", "pattern3.csv", pattern)
    write("pattern_csv", "pattern3_crlf_gaps.csv", pattern.replace("\n", "\r\n").replace("5,", "\r\n5,"))

    # --- scene JSON (opl_simulate images --scene; opl_measure --images --scene)
    scene = json.loads(read(os.path.join(EXAMPLES, "scene_small.json")))
    scene["module"] = "aux/scene_small_module.json"
    write("scene_json", "aux/scene_small_module.json", read(os.path.join(EXAMPLES, "scene_small_module.json")))
    write("scene_json", "scene_small.json", json.dumps(scene, indent=2))
    inline = json.loads(json.dumps(scene))
    inline["module"] = json.loads(read(os.path.join(EXAMPLES, "scene_small_module.json")))
    inline["cameras"] = inline["cameras"][:1]
    inline["shots"] = [s for s in inline["shots"] if s["camera"] == "cam0"]
    write("scene_json", "inline_module.json", json.dumps(inline))
    measured = json.loads(json.dumps(scene))  # a measured scene: no poses, placements ids only
    for cam in measured["cameras"]:
        del cam["pose"]
    measured["tags"]["placements"] = [{"id": p["id"]} for p in measured["tags"]["placements"]]
    for k in ("spots", "image", "seed"):
        del measured[k]
    write("scene_json", "measured.json", json.dumps(measured, indent=1))
    dark = json.loads(json.dumps(scene))  # item 5: no shot has a laser on
    for s in dark["shots"]:
        s["lasers"] = []
    write("scene_json", "no_lasers.json", json.dumps(dark))
    write("scene_json", "deep_nesting.json", deep_json())
    cal_scene = json.loads(read(os.path.join(EXAMPLES, "calibration_session_small.json")))
    if isinstance(cal_scene.get("module"), str):
        cal_scene["module"] = "aux/" + os.path.basename(cal_scene["module"])
        write("scene_json", cal_scene["module"],
              read(os.path.join(EXAMPLES, os.path.basename(cal_scene["module"][4:]))))
    write("scene_json", "calibration_session_small.json", json.dumps(cal_scene, indent=1))

    # --- the tools' scene (tests/fuzz/cli_fuzz_test.cc): one 320 x 240 camera, two shots
    tiny = json.loads(read(os.path.join(EXAMPLES, "scene_small.json")))
    tiny["description"] = ("Fuzz corpus of the tools: examples/scene_small.json with one "
                           "320 x 240 camera (cam0), two shots.")
    cam = tiny["cameras"][0]
    cam["width_px"], cam["height_px"] = 320, 240
    cam["intrinsics"].update({"fx": 312.5, "fy": 312.5, "cx": 159.5, "cy": 119.5})
    tiny["cameras"] = [cam]
    tiny["shots"] = [s for s in tiny["shots"] if s["camera"] == "cam0"]
    tiny["module"] = "aux/module.json"
    write("cli_scene_json", "tiny_scene.json", json.dumps(tiny, indent=1) + "\n")
    write("cli_scene_json", "aux/module.json", read(os.path.join(EXAMPLES, "scene_small_module.json")))

    # --- cameras JSON (opl_scene init --cameras); item 6: intrinsics out of range
    camera = {"name": "cam0", "width_px": 640, "height_px": 480,
              "intrinsics": {"fx": 536.46, "fy": 536.41, "cx": 342.37, "cy": 235.55, "k1": -0.2786,
                             "k2": 0.0672, "p1": 0.00182, "p2": -0.00034, "k3": 0},
              "calibration": {"intrinsics_std": {"fx": 0.88, "fy": 0.92, "cx": 0.97, "cy": 1.07,
                                                 "k1": 0.0047, "k2": 0.017, "p1": 0.00024, "p2": 0.0003,
                                                 "k3": 0},
                              "rms_px": 0.409, "views": 13, "corners": 702,
                              "board": "chessboard 9 x 6 inner corners, square 25 mm"}}
    write("cameras_json", "one_camera.json", json.dumps({"format": "opl.cameras", "version": 1, "cameras": [camera]}, indent=1))
    two = [camera, dict(camera, name="cam1", calibration=None)]
    del two[1]["calibration"]
    write("cameras_json", "two_cameras.json", json.dumps({"format": "opl.cameras", "version": 1, "cameras": two}))
    for field, value in (("fx", 1e308), ("k1", 1e6)):
        bad = json.loads(json.dumps(camera))
        bad["intrinsics"][field] = value
        write("cameras_json", "%s_%g.json" % (field, value),
              json.dumps({"format": "opl.cameras", "version": 1, "cameras": [bad]}))

    # --- board JSON (opl_camera calibrate --board)
    write("board_json", "tag_grid.json", '{"format": "opl.board", "version": 1, "type": "tag_grid",\n'
          ' "family": "tag36h11", "cols": 6, "rows": 4, "first_id": 0,\n "tag_size_mm": 30, "gap_mm": 7.5}\n')
    write("board_json", "tag_grid_pitch.json", '{"format": "opl.board", "version": 1, "type": "tag_grid", '
          '"family": "tag36h11", "cols": 3, "rows": 2, "first_id": 10, "tag_size_mm": 30, "pitch_mm": 40}')
    write("board_json", "chessboard.json", '{"format": "opl.board", "version": 1, "type": "chessboard",\n'
          ' "inner_cols": 9, "inner_rows": 6, "square_mm": 25}\n')

    # --- the sequencer's frame metadata (opl_scene init --metadata)
    frames = []
    for run_, seq in ((1, "measurement"), (2, "calibration")):
        for i, (step, lasers) in enumerate((("grid_a", (True, False)), ("grid_b", (False, True)),
                                            ("both", (True, True)), ("dark", (False, False)))):
            frames.append(json.dumps({"t_ns": 591826816602 + 1000 * i, "time": "2026-11-22T00:36:12.486753Z",
                                      "sequence": seq, "run": run_, "slice": 0, "step": step,
                                      "step_index": i, "frame": i,
                                      "lasers": {"a": lasers[0], "b": lasers[1]}, "blocker": "closed"},
                                     separators=(",", ":")))
    write("frames_jsonl", "two_runs.jsonl", "\n".join(frames) + "\n")
    write("frames_jsonl", "manual_crlf.jsonl",
          '{"t_ns":7,"time":"x","sequence":"manual","run":2,"slice":null,"step":"manual","step_index":null,'
          '"frame":0,"lasers":{"a":false,"b":false},"blocker":"open","future_field":[1,2]}\r\n\r\n')
    shutil.rmtree(tmp)
    images()


def images():
    import io
    from PIL import Image, PngImagePlugin

    w, h = 40, 30
    grey = Image.new("L", (w, h))
    grey.putdata([(16 * x + 8 * y + (200 if (x - 20) ** 2 + (y - 15) ** 2 < 16 else 0)) % 256
                  for y in range(h) for x in range(w)])
    rgb = Image.merge("RGB", (grey, grey.transpose(Image.FLIP_LEFT_RIGHT), grey.transpose(Image.FLIP_TOP_BOTTOM)))

    def encoded(image, fmt, **options):
        out = io.BytesIO()
        image.save(out, fmt, **options)
        return out.getvalue()

    write("png", "grey8.png", encoded(grey, "PNG"))
    write("png", "rgb8.png", encoded(rgb, "PNG", compress_level=9))
    write("png", "rgba8.png", encoded(rgb.convert("RGBA"), "PNG"))
    write("png", "grey16.png", encoded(grey.point(lambda v: v * 257, "I").convert("I;16"), "PNG"))
    write("png", "palette.png", encoded(rgb.convert("P", palette=Image.ADAPTIVE, colors=16), "PNG"))
    write("png", "bilevel.png", encoded(grey.convert("1"), "PNG"))
    info = PngImagePlugin.PngInfo()
    info.add_text("Comment", "ancillary chunks: libpng may warn about them on stderr")
    info.add_text("Software", "x" * 100, zip=True)
    write("png", "text_chunks_trns.png", encoded(grey, "PNG", pnginfo=info, transparency=0))
    # issue 19 item 1: 60 bytes claiming 100000 x 100000 pixels (uncaught OpenCV assertion).
    huge = b"\x89PNG\r\n\x1a\n" + b"\0\0\0\x0dIHDR" + b"\0\x01\x86\xa0\0\x01\x86\xa0\x08\x02\0\0\0"
    write("png", "header_100000x100000.png", huge + b"\0" * (60 - len(huge)))

    write("jpeg", "grey.jpg", encoded(grey, "JPEG", quality=90))
    write("jpeg", "rgb_420.jpg", encoded(rgb, "JPEG", quality=75, subsampling=2))
    write("jpeg", "rgb_444_progressive.jpg", encoded(rgb, "JPEG", quality=95, subsampling=0, progressive=True))
    exif = Image.Exif()
    exif[0x0112] = 6  # orientation: rotate 90 (ignored: sensor pixels)
    write("jpeg", "exif_orientation.jpg", encoded(rgb, "JPEG", quality=80, exif=exif.tobytes()))
    # The same header attack for JPEG: the frame header says 65500 x 65500.
    data = bytearray(encoded(grey, "JPEG", quality=50))
    sof = data.index(b"\xff\xc0")
    data[sof + 5:sof + 9] = b"\xff\xdc\xff\xdc"
    write("jpeg", "header_65500x65500.jpg", bytes(data))


if __name__ == "__main__":
    main()
