#!/usr/bin/env python3
"""Every JSON file OPL reads or writes validates against its schema in docs/schemas/.

1. Every schema is itself valid (JSON Schema draft 2020-12 metaschema).
2. Every JSON file in examples/ and tests/data/ validates against the schema
   its "format" names (files without "format" by their place: the sequencer
   configurations). A JSON file with no schema fails the test.
3. The tools are run on the bundled examples to write every JSON output
   (opl_simulate calibration / mc --json [--samples] / mc --calibration --json / images
   truth.json, opl_calibrate --out, opl_measure --json (spots and images),
   opl_camera board --board-json / calibrate --out --report, opl_scene init,
   opl_verify --json,
   opl_sequencer's per-frame metadata and simulated-chip log), and each
   validates. Each is validated again with a "provenance" record (the one
   opl_scene wrote) added at its top level: the shared provenance schema is
   allowed everywhere.
4. Negative cases: a missing required field, a wrong type, an unknown field
   (where the reader refuses them) and a bad provenance are rejected.

Usage: validate_json_test.py --source-dir SRC --bin-dir BUILD/apps [--keep DIR]
Needs python3-jsonschema (Debian 12: 4.10.3; works with later versions).
"""
import argparse
import copy
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import jsonschema
from jsonschema import Draft202012Validator

FORMAT_TO_SCHEMA = {
    "opl.scene": "scene",
    "opl.cameras": "cameras",
    "opl.board": "board",
    "opl.module_design": "module_design",
    "opl.module_calibration": "module_calibration",
    "opl.scene_truth": "scene_truth",
    "opl.measure_report": "measure_report",
    "opl.image_measure_report": "image_measure_report",
    "opl.camera_calibration_report": "camera_calibration_report",
    "opl.monte_carlo_report": "monte_carlo_report",
    "opl.calibration_monte_carlo_report": "calibration_monte_carlo_report",
    "opl.verify_report": "verify_report",
}

failures = []
checked = []


def fail(message):
    failures.append(message)
    print("FAIL: " + message, flush=True)


class Schemas:
    def __init__(self, folder):
        self.schemas = {}
        for path in sorted(glob.glob(os.path.join(folder, "*.schema.json"))):
            name = os.path.basename(path)[: -len(".schema.json")]
            with open(path, encoding="utf-8") as f:
                self.schemas[name] = json.load(f)
        try:  # jsonschema >= 4.18
            from referencing import Registry, Resource
            from referencing.jsonschema import DRAFT202012

            registry = Registry().with_resources(
                (s["$id"], Resource.from_contents(s, default_specification=DRAFT202012))
                for s in self.schemas.values())
            self._make = lambda schema: Draft202012Validator(schema, registry=registry)
        except ImportError:  # Debian 12's 4.10.3
            store = {s["$id"]: s for s in self.schemas.values()}
            self._make = lambda schema: Draft202012Validator(
                schema, resolver=jsonschema.RefResolver.from_schema(schema, store=store))
        self._validators = {}

    def check_all(self):
        for name, schema in self.schemas.items():
            try:
                Draft202012Validator.check_schema(schema)
            except jsonschema.exceptions.SchemaError as e:
                fail("docs/schemas/%s.schema.json is not a valid schema: %s" % (name, e.message))
            if schema.get("$id") != "https://schemas.opl.invalid/%s.schema.json" % name:
                fail("docs/schemas/%s.schema.json: $id does not name the file" % name)

    def errors(self, instance, name):
        if name not in self._validators:
            self._validators[name] = self._make(self.schemas[name])
        return sorted(self._validators[name].iter_errors(instance), key=lambda e: list(e.absolute_path))


def schema_of(document, path):
    if isinstance(document, dict) and isinstance(document.get("format"), str):
        return FORMAT_TO_SCHEMA.get(document["format"])
    if "/sequencer/" in path.replace(os.sep, "/") and path.endswith(".json"):
        return "sequencer_config"
    return None


def expect_valid(schemas, document, name, what):
    errors = schemas.errors(document, name)
    checked.append((what, name))
    if errors:
        e = errors[0]
        fail("%s does not validate against %s.schema.json: at /%s: %s" % (
            what, name, "/".join(str(p) for p in e.absolute_path), e.message))
    else:
        print("ok   %-60s %s" % (what, name), flush=True)


def expect_invalid(schemas, document, name, what):
    if not schemas.errors(document, name):
        fail("%s: %s.schema.json accepts it but must reject it" % (what, name))
    else:
        print("ok   rejected: %s" % what, flush=True)


def validate_file(schemas, path, label=None, jsonl=False):
    label = label or path
    with open(path, encoding="utf-8") as f:
        text = f.read()
    documents = []
    if jsonl:
        for number, line in enumerate(text.splitlines(), 1):
            if line.strip():
                documents.append(("%s:%d" % (label, number), json.loads(line)))
    else:
        documents.append((label, json.loads(text)))
    return documents


def run(command, cwd=None, timeout=600):
    print("run  " + " ".join(command), flush=True)
    r = subprocess.run(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout,
                       universal_newlines=True)
    if r.returncode != 0:
        fail("%s exited %d: %s" % (" ".join(command), r.returncode, r.stderr.strip()[-500:]))
        return None
    return r.stdout


class Tools:
    def __init__(self, bin_dir):
        self.bin_dir = bin_dir

    def path(self, name):
        for candidate in (os.path.join(self.bin_dir, name), os.path.join(self.bin_dir, "sequencer", name)):
            if os.access(candidate, os.X_OK):
                return candidate
        return None


def produce_outputs(src, tools, work):
    """Runs the tools; returns [(label, path or text, jsonl)] of JSON outputs."""
    ex = os.path.join(src, "examples")
    out = []
    sim, measure, calibrate = tools.path("opl_simulate"), tools.path("opl_measure"), tools.path("opl_calibrate")
    camera, scene_tool, sequencer = tools.path("opl_camera"), tools.path("opl_scene"), tools.path("opl_sequencer")
    for name, exe in (("opl_simulate", sim), ("opl_measure", measure), ("opl_calibrate", calibrate),
                      ("opl_camera", camera), ("opl_scene", scene_tool)):
        if exe is None:
            fail("%s not found in %s" % (name, tools.bin_dir))
    if None in (sim, measure, calibrate, camera, scene_tool):
        return out
    w = lambda name: os.path.join(work, name)

    # Module calibration (opl_simulate), spots, the measure report.
    if run([sim, "calibration", "--design", ex + "/prototype_design.json", "--out", w("cal.json")]) is not None:
        out.append(("opl_simulate calibration --out", w("cal.json"), False))
    if run([sim, "spots", "--design", ex + "/prototype_design.json", "--out", w("spots.csv")]) is not None:
        text = run([measure, "--calibration", w("cal.json"), "--spots", w("spots.csv"), "--json"])
        if text is not None:
            out.append(("opl_measure --spots --json", text, None))
    # With identification (unassigned spots): the report's "identification".
    text = run([measure, "--calibration", ex + "/prototype_calibration.json", "--spots",
                ex + "/prototype_spots.csv", "--json"])
    if text is not None:
        out.append(("opl_measure --json (prototype)", text, None))
    # Monte Carlo reports.
    text = run([sim, "mc", "--design", ex + "/prototype_design.json", "--iterations", "20", "--threads", "2",
                "--json"])
    if text is not None:
        out.append(("opl_simulate mc --json", text, None))
    text = run([sim, "mc", "--design", ex + "/prototype_design.json", "--iterations", "20", "--threads", "2",
                "--json", "--samples"])
    if text is not None:
        out.append(("opl_simulate mc --json --samples", text, None))
    text = run([sim, "mc", "--calibration", "--design", ex + "/prototype_design.json", "--iterations", "3",
                "--threads", "2", "--json"])
    if text is not None:
        out.append(("opl_simulate mc --calibration --json", text, None))
    # A calibration from slices (opl_calibrate writes the quality records).
    if run([sim, "slices", "--design", ex + "/prototype_design.json", "--depths", "750:130:1270", "--out",
            w("slices.csv")]) is not None:
        if run([calibrate, "--spots", w("slices.csv"), "--allow-extra-columns", "--out", w("cal2.json")]) is not None:
            out.append(("opl_calibrate --out", w("cal2.json"), False))
    # Images: the truth, the image measure report.
    shots = w("shots")
    if run([sim, "images", "--scene", ex + "/scene_small.json", "--out", shots]) is not None:
        out.append(("opl_simulate images truth.json", os.path.join(shots, "truth.json"), False))
        if run([sim, "calibration", "--design", ex + "/scene_small_module.json", "--out",
                w("small_cal.json")]) is not None:
            text = run([measure, "--calibration", w("small_cal.json"), "--images", shots, "--scene",
                        ex + "/scene_small.json", "--json"])
            if text is not None:
                out.append(("opl_measure --images --json", text, None))
            # The acceptance test's report: the same scene with check lengths.
            verify = tools.path("opl_verify")
            if verify is not None:
                with open(ex + "/scene_small.json", encoding="utf-8") as f:
                    checked_scene = json.load(f)
                checked_scene["module"] = ex + "/scene_small_module.json"
                centres = {t["id"]: t["center_mm"] for t in checked_scene["tags"]["placements"]}
                checked_scene["check_lengths"] = [
                    {"name": "t%d-t%d" % (a, b), "tag_1": a, "tag_2": b,
                     "length_mm": sum((centres[a][k] - centres[b][k]) ** 2 for k in range(3)) ** 0.5,
                     "length_sigma_mm": 0.002} for a, b in ((0, 3), (4, 5), (6, 7))]
                with open(w("checked_scene.json"), "w", encoding="utf-8") as f:
                    json.dump(checked_scene, f)
                if run([verify, "--scene", w("checked_scene.json"), "--images", shots, "--calibration",
                        w("small_cal.json"), "--json", w("verify.json")]) is not None:
                    out.append(("opl_verify --json", w("verify.json"), False))
            else:
                print("note: opl_verify not built: its report not validated", flush=True)
    # Boards and cameras.
    if run([camera, "board", "--out", w("board.png"), "--cols", "4", "--rows", "3", "--tag-mm", "30",
            "--gap-mm", "7.5", "--dpi", "100", "--board-json", w("board.json")]) is not None:
        out.append(("opl_camera board --board-json", w("board.json"), False))
    lefts = sorted(glob.glob("/usr/share/doc/opencv-doc/examples/data/left0*.jpg"))
    if lefts:
        if run([camera, "calibrate", "--images"] + lefts + ["--chessboard", "9x6", "--square-mm", "25", "--out",
                                                             w("cameras.json"), "--report", w("camrep")]) is not None:
            out.append(("opl_camera calibrate --out", w("cameras.json"), False))
            out.append(("opl_camera calibrate --report", w("camrep/camera_report.json"), False))
    else:
        print("note: opencv-doc's left0*.jpg not installed: opl_camera calibrate not run", flush=True)
    # The sequencer: a measurement on the simulated chip; its metadata and log.
    frames = w("frames.jsonl")
    if sequencer is not None:
        with open(ex + "/sequencer/sequencer-sim.json", encoding="utf-8") as f:
            config = json.load(f)
        config["gpio"]["sim_log"] = w("sim.jsonl")
        config["socket"] = w("seq.sock")
        config["metadata"] = frames
        with open(w("sequencer.json"), "w", encoding="utf-8") as f:
            json.dump(config, f)
        daemon = subprocess.Popen([sequencer, "daemon", "-c", w("sequencer.json")], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE)
        try:
            for _ in range(200):
                if os.path.exists(w("seq.sock")):
                    break
                time.sleep(0.05)
            if run([sequencer, "client", "-c", w("sequencer.json"), "start", "measurement", "--no-stdin"],
                   timeout=60) is not None:
                out.append(("opl_sequencer per-frame metadata", frames, True))
                out.append(("opl_sequencer simulated-chip log", w("sim.jsonl"), True))
        finally:
            daemon.send_signal(signal.SIGTERM)
            try:
                daemon.wait(timeout=10)
            except subprocess.TimeoutExpired:
                daemon.kill()
                daemon.wait()
    else:
        print("note: opl_sequencer not built: metadata written by hand for opl_scene init", flush=True)
    if not os.path.exists(frames):
        with open(frames, "w", encoding="utf-8") as f:
            for k, (a, b) in enumerate(((True, False), (False, True), (True, True), (False, False))):
                f.write(json.dumps({"sequence": "measurement", "run": 1, "slice": 0, "frame": k,
                                    "lasers": {"a": a, "b": b}}) + "\n")
    # opl_scene init: the four frames, one camera (symlinks to rendered images).
    if os.path.isdir(shots):
        # The rendered images' camera (scene_small's cam0, 1024 x 768), as a
        # cameras JSON (opl_camera's above calibrated 640 x 480 photographs).
        with open(ex + "/scene_small.json", encoding="utf-8") as f:
            camera = json.load(f)["cameras"][0]
        del camera["pose"]
        with open(w("cam0.json"), "w", encoding="utf-8") as f:
            json.dump({"format": "opl.cameras", "version": 1, "cameras": [camera]}, f)
        session = w("session")
        os.makedirs(session, exist_ok=True)
        for k, name in enumerate(("cam0_A.png", "cam0_B.png", "cam0_A.png", "cam0_B.png")):
            os.symlink(os.path.join(shots, name), os.path.join(session, "IMG_%04d.png" % k))
        if run([scene_tool, "init", "--images", session, "--cameras", w("cam0.json"), "--metadata", frames,
                "--tag-size-mm", "140", "--frame", "0,1,2", "--out", w("scene.json")]) is not None:
            out.append(("opl_scene init --out", w("scene.json"), False))
    return out


def negative_cases(schemas, documents):
    """documents: format -> a valid document of it."""
    def mutated(fmt, change):
        d = copy.deepcopy(documents[fmt])
        change(d)
        return d

    def drop(*path):
        def change(d):
            for p in path[:-1]:
                d = d[p]
            del d[path[-1]]
        return change

    def setv(value, *path):
        def change(d):
            for p in path[:-1]:
                d = d[p]
            d[path[-1]] = value
        return change

    cases = [
        ("opl.scene", drop("shots"), "scene without shots (required)"),
        ("opl.scene", setv("1024", "cameras", 0, "width_px"), "scene camera width_px as a string"),
        ("opl.scene", setv("A", "shots", 0, "lasers"), "scene shot lasers not an array"),
        ("opl.scene", setv({}, "modul"), "scene with an unknown field 'modul'"),
        ("opl.scene", setv(-1, "tags", "size_mm"), "scene tags.size_mm < 0"),
        ("opl.scene", setv({"tool": "x"}, "provenance"), "scene provenance without version, time, inputs"),
        ("opl.cameras", drop("cameras", 0, "intrinsics", "fx"), "camera without intrinsics.fx"),
        ("opl.cameras", setv(0, "cameras", 0, "intrinsics", "fy"), "camera fy = 0"),
        ("opl.board", setv(7.5, "pitch_mm"), "tag grid board with both gap_mm and pitch_mm"),
        ("opl.board", drop("tag_size_mm"), "tag grid board without tag_size_mm"),
        ("opl.module_calibration", drop("units"), "calibration without units"),
        ("opl.module_calibration", setv("0.1", "sources", 0, "beams", 0, "az_rad"), "beam az_rad as a string"),
        ("opl.module_calibration", setv(10, "sources", 0, "beams_per_side"), "even beams_per_side"),
        ("opl.module_design", setv("29", "sources", 0, "full_angle_deg"), "design full_angle_deg as a string"),
        ("opl.module_design", setv({"type": "cube"}, "surface"), "design surface of an unknown type"),
        ("opl.measure_report", setv("1.0", "scale_factor"), "measure report scale_factor as a string"),
        ("opl.measure_report", drop("lengths"), "measure report without lengths"),
        ("opl.image_measure_report", drop("measure", "scale_factor"), "image report's measure without s"),
        ("opl.image_measure_report", setv("yes", "images", 0, "placed"), "image report placed as a string"),
        ("opl.scene_truth", setv([1, 2], "tags", 0, "center_mm"), "truth tag centre of 2 numbers"),
        ("opl.camera_calibration_report", drop("rms_px"), "camera report without rms_px"),
        ("opl.monte_carlo_report", setv("20", "iterations"), "MC report iterations as a string"),
        ("opl.monte_carlo_report", setv(["55.1"], "lengths", 0, "samples_mm"), "MC L sample as a string"),
        ("opl.monte_carlo_report", setv([[0.0, 19.5]], "sources", 0, "origin_samples_mm"),
         "MC origin sample of 2 numbers"),
        ("opl.monte_carlo_report", setv([-1], "sample_iterations"), "MC sample iteration -1"),
        ("opl.calibration_monte_carlo_report", drop("lengths"), "calibration MC report without lengths"),
        ("sequencer_frame", setv(1, "lasers", "a"), "metadata line with lasers.a = 1"),
        ("sequencer_frame", drop("run"), "metadata line without run"),
        ("sequencer_frame", setv(None, "slice"), "measurement metadata line with slice null"),
        ("sequencer_config", setv("17", "lines", "laser_a", "offset"), "sequencer config offset as a string"),
        ("sequencer_config", setv(5, "max_laser_on"), "sequencer config with a misplaced key"),
        ("sequencer_sim_log", setv(2, "value"), "sim log line with value 2"),
    ]
    for fmt, change, what in cases:
        if fmt not in documents:
            fail("no valid %s document to mutate for the negative case '%s'" % (fmt, what))
            continue
        name = FORMAT_TO_SCHEMA.get(fmt, fmt)
        expect_invalid(schemas, mutated(fmt, change), name, what)
    # Every format: a missing "format" or a version of another type is rejected.
    for fmt, document in documents.items():
        if fmt not in FORMAT_TO_SCHEMA:
            continue
        name = FORMAT_TO_SCHEMA[fmt]
        expect_invalid(schemas, mutated(fmt, drop("format")), name, "%s without format" % fmt)
        expect_invalid(schemas, mutated(fmt, setv("1", "version")), name, "%s with version \"1\"" % fmt)
    # A provenance record with a bad digest, anywhere.
    if "provenance" in documents:
        bad = copy.deepcopy(documents["provenance"])
        bad["inputs"] = [{"path": "x", "bytes": 1, "sha256": "abc"}]
        expect_invalid(schemas, bad, "provenance", "provenance with a 3-digit sha256")
        bad = copy.deepcopy(documents["provenance"])
        bad["time_utc"] = "yesterday"
        expect_invalid(schemas, bad, "provenance", "provenance time_utc 'yesterday'")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--bin-dir", required=True)
    parser.add_argument("--keep", help="write the outputs in this folder and keep them")
    args = parser.parse_args()
    src = os.path.abspath(args.source_dir)
    schemas = Schemas(os.path.join(src, "docs", "schemas"))
    if not schemas.schemas:
        fail("no schema in docs/schemas")
        return 1
    schemas.check_all()
    valid = {}  # format -> a valid document

    def take(label, document):
        fmt = document.get("format") if isinstance(document, dict) else None
        if isinstance(fmt, str) and not fmt.startswith("opl."):
            # Another program's file (tests/data/independent_renders: an
            # independent renderer's truth, "indep.scene_truth").
            print("note: %s: format %r is not OPL's: not validated" % (label, fmt), flush=True)
            return
        name = schema_of(document, label)
        if name is None:
            fail("%s: no schema for this JSON (format %r): add one to docs/schemas/" % (
                label, document.get("format") if isinstance(document, dict) else None))
            return
        expect_valid(schemas, document, name, label)
        key = document.get("format", name) if isinstance(document, dict) else name
        valid.setdefault(key, document)

    # 2. The bundled JSON files.
    files = sorted(glob.glob(os.path.join(src, "examples", "**", "*.json"), recursive=True) +
                   glob.glob(os.path.join(src, "tests", "data", "**", "*.json"), recursive=True))
    for path in files:
        for label, document in validate_file(schemas, path, os.path.relpath(path, src)):
            take(label, document)

    # 3. The tools' outputs.
    work = args.keep or tempfile.mkdtemp(prefix="opl_schemas_")
    if args.keep:
        shutil.rmtree(work, ignore_errors=True)
        os.makedirs(work)
    try:
        outputs = produce_outputs(src, Tools(os.path.abspath(args.bin_dir)), work)
        documents = []
        for label, content, jsonl in outputs:
            if jsonl is None:
                documents.append((label, json.loads(content)))
            else:
                documents += validate_file(schemas, content, label, jsonl)
        provenance = None
        for label, document in documents:
            if jsonl_schema(label):
                name = jsonl_schema(label)
                expect_valid(schemas, document, name, label)
                valid.setdefault(name, document)
            else:
                take(label, document)
            if isinstance(document, dict) and "provenance" in document and provenance is None:
                provenance = document["provenance"]
        if provenance is None:
            fail("no tool output carries a provenance record (opl_scene init writes one)")
        else:
            expect_valid(schemas, provenance, "provenance", "provenance of opl_scene init")
            valid["provenance"] = provenance
            for label, document in documents:
                if isinstance(document, dict) and "format" in document:
                    with_provenance = dict(document, provenance=provenance)
                    expect_valid(schemas, with_provenance, schema_of(document, label),
                                 label + " + provenance")
        produced = {schema_of(d, l) for l, d in documents if isinstance(d, dict)}
        for fmt in ("opl.scene", "opl.cameras", "opl.board", "opl.module_calibration", "opl.scene_truth",
                    "opl.measure_report", "opl.image_measure_report", "opl.camera_calibration_report",
                    "opl.monte_carlo_report", "opl.calibration_monte_carlo_report"):
            if FORMAT_TO_SCHEMA[fmt] not in produced:
                print("note: no tool output of %s this run" % fmt, flush=True)
        # 4. Negative cases.
        negative_cases(schemas, valid)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    used = {name for _, name in checked}
    for name in schemas.schemas:
        if name not in used and name not in ("common", "provenance"):
            fail("docs/schemas/%s.schema.json validated no document" % name)
    print("%d documents validated, %d failures" % (len(checked), len(failures)))
    return 1 if failures else 0


def jsonl_schema(label):
    if label.startswith("opl_sequencer per-frame metadata"):
        return "sequencer_frame"
    if label.startswith("opl_sequencer simulated-chip log"):
        return "sequencer_sim_log"
    return None


if __name__ == "__main__":
    sys.exit(main())
