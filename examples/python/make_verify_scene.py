#!/usr/bin/python3
"""Writes examples/scene_verify_18mp.json and its module design: the
acceptance test of issue 20 (VDI/VDE 2634 Part 1, ISO 10360-13) in the
virtual lab (docs/verify.md).

The measuring volume is a box of 2 x 2 x 1.5 m: x from 500 to 2500 mm
(depth, away from the cameras), y from -1000 to 1000 mm, z from -750 to
750 mm (Z up). Tags (tag36h11, 140 mm) sit
  - on the back wall (x = 2500, facing the cameras): the three frame tags
    and a fourth, at the wall's corners around the laser grids;
  - on two posts at the front corners (x = 500, y = +-1000), low and high
    (z = +-700), turned towards the cameras;
  - on two stands at the sides (y = +-1000) at mid-depth, turned 45 deg
    towards the cameras;
  - on two wedges on the floor (z = -750), tilted 45 deg up towards the
    cameras;
  - on a 1200 mm scale bar lying on the floor (the scene's `artifact`, the
    conventional scale the OPL column is compared with).
Check lengths join tags through the volume: the four space diagonals, edges
along x, y and z, and a floor diagonal; each one's length_mm is the true
distance of the two tag centres computed here (the scene JSON places them
exactly), with the 2 um standard uncertainty of a calibrated bar.

Six 18 MP cameras (4912 x 3684, fx 4000 px, as scene_18mp.json): four in
front of the volume (x = -1800 and -1700, at two heights), two wider apart;
each takes one image with laser A and one with laser B. The module
(scene_verify_18mp_module.json: the prototype's two 11 x 11 sources, 29 deg,
55 mm apart) stands at the front of the volume (x = 500) and throws its grids
on the back wall.

Run from anywhere: /usr/bin/python3 examples/python/make_verify_scene.py
It prints every check length and, per camera, the tags in the image with
their smallest distance to the border and their viewing angle, and refuses
(exit 1) a layout where a tag leaves an image or overlaps the laser grid.
"""
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLES = os.path.dirname(HERE)
SCENE = os.path.join(EXAMPLES, "scene_verify_18mp.json")
MODULE = os.path.join(EXAMPLES, "scene_verify_18mp_module.json")

TAG_MM = 140.0
WALL_X = 2500.0          # back wall, where the grids land
MODULE_X = 500.0         # module's projection origins (x)
WIDTH, HEIGHT, F = 4912, 3684, 4000.0
CAMERA_CENTROID = (-1500.0, 0.0, 200.0)  # what the posts' tags face


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def add(a, b):
    return [a[i] + b[i] for i in range(3)]


def mul(a, k):
    return [a[i] * k for i in range(3)]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def norm(a):
    return math.sqrt(dot(a, a))


def unit(a):
    n = norm(a)
    return [x / n for x in a]


def up_in_plane(normal):
    """World Z projected on the tag's plane (or +x when the tag is level)."""
    z = [0.0, 0.0, 1.0]
    u = sub(z, mul(normal, dot(z, normal)))
    if norm(u) < 1e-6:
        u = [1.0, 0.0, 0.0]
    return unit(u)


TAGS = {}  # id -> (centre, normal)


def tag(tag_id, centre, normal):
    TAGS[tag_id] = ([float(c) for c in centre], unit(normal))


def facing_cameras(centre):
    return unit(sub(CAMERA_CENTROID, centre))


# Back wall: the frame tags 0, 1, 2 and a fourth, at the corners of the
# wall around the grids (which cover +-517 mm about the wall's centre).
back = [-1.0, 0.0, 0.0]
tag(0, [WALL_X, -800, -650], back)   # frame origin
tag(1, [WALL_X, 800, -650], back)    # frame axis
tag(2, [WALL_X, -800, 700], back)    # frame plane
tag(3, [WALL_X, 800, 700], back)
# Posts at the front corners, low and high, facing the cameras.
for tag_id, centre in ((10, [500, -1000, -700]), (11, [500, -1000, 700]),
                       (12, [500, 1000, -700]), (13, [500, 1000, 700])):
    tag(tag_id, centre, facing_cameras(centre))
# Stands at the sides at mid-depth, turned 45 deg towards the cameras.
tag(14, [1600, -1000, 250], [-1, 1, 0])
tag(15, [1600, 1000, -250], [-1, -1, 0])
# Wedges on the floor, tilted 45 deg up towards the cameras.
tag(16, [1000, -100, -750], [-1, 0, 1])
tag(17, [2300, 250, -750], [-1, 0, 1])
# The scale bar (artifact) on the floor, 1200 mm, its tags on 45 deg wedges.
tag(20, [1000, -600, -700], [-1, 0, 1])
tag(21, [1000, 600, -700], [-1, 0, 1])
BAR = (20, 21)

CHECKS = [
    # (name, tag_1, tag_2): the space diagonals, then edges and a floor diagonal.
    ("diag_1", 10, 3),
    ("diag_2", 12, 2),
    ("diag_3", 11, 1),
    ("diag_4", 13, 0),
    ("edge_x_low", 10, 0),
    ("edge_x_high", 13, 3),
    ("edge_y_front", 10, 12),
    ("edge_z_post", 12, 13),
    ("edge_y_sides", 14, 15),
    ("floor_diag", 16, 17),
]
CHECK_SIGMA_MM = 0.002

# Cameras: (name, centre, look_at, roll_deg).
CAMERAS = [
    ("cam0", [-1800, 600, 700], [1500, 0, -100], 2.0),
    ("cam1", [-1800, -600, 700], [1500, 0, -100], -1.5),
    ("cam2", [-1700, 600, -200], [1500, 0, -100], 1.0),
    ("cam3", [-1700, -600, -200], [1500, 0, -100], -2.5),
    ("cam4", [-1800, 1300, 0], [1500, 0, -100], 0.5),
    ("cam5", [-1800, -1300, 0], [1500, 0, -100], -0.5),
]


def camera_axes(centre, look_at, roll_deg):
    z = unit(sub(look_at, centre))
    x = unit(cross(z, [0.0, 0.0, 1.0]))
    y = cross(z, x)
    r = math.radians(roll_deg)
    xr = add(mul(x, math.cos(r)), mul(y, math.sin(r)))
    yr = add(mul(y, math.cos(r)), mul(x, -math.sin(r)))
    return xr, yr, z


def project(cam, p):
    _, centre, look_at, roll = cam
    x, y, z = camera_axes(centre, look_at, roll)
    d = sub(p, centre)
    zc = dot(d, z)
    if zc <= 0:
        return None
    return (F * dot(d, x) / zc + (WIDTH - 1) / 2.0, F * dot(d, y) / zc + (HEIGHT - 1) / 2.0)


def tag_corners(centre, normal, half):
    up = up_in_plane(normal)
    right = cross(up, normal)  # x right as printed, seen from the front
    return [add(centre, add(mul(right, sx * half), mul(up, sy * half)))
            for sx, sy in ((-1, 1), (1, 1), (1, -1), (-1, -1))]


def grid_points():
    """The two grids' spots on the back wall (equal-angle 11 x 11, 29 deg)."""
    pts = []
    step = math.radians(29.0) / 10.0
    for y0 in (27.5, -27.5):
        for i in range(-5, 6):
            for j in range(-5, 6):
                dy, dz = math.tan(i * step), math.tan(j * step)
                pts.append([WALL_X, y0 + (WALL_X - MODULE_X) * dy, (WALL_X - MODULE_X) * dz])
    return pts


def bbox(points):
    us = [p[0] for p in points]
    vs = [p[1] for p in points]
    return min(us), min(vs), max(us), max(vs)


def convex_hull(points):
    """Andrew's monotone chain; counter-clockwise in (u, v)."""
    pts = sorted(set(points))

    def turn(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and turn(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and turn(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def distance_outside(hull, p):
    """How far p is outside the convex polygon (<= 0 inside)."""
    worst = -1e30
    for i in range(len(hull)):
        a, b = hull[i], hull[(i + 1) % len(hull)]
        ex, ey = b[0] - a[0], b[1] - a[1]
        # outward normal of a counter-clockwise edge
        nx, ny = ey, -ex
        n = math.hypot(nx, ny)
        worst = max(worst, ((p[0] - a[0]) * nx + (p[1] - a[1]) * ny) / n)
    return worst


def quad_near_hull(quad, hull, margin):
    """True when any point of the (convex) quad comes within margin of the hull."""
    for i in range(11):
        for j in range(11):
            a, b = i / 10.0, j / 10.0
            top = [quad[0][k] + a * (quad[1][k] - quad[0][k]) for k in range(2)]
            bottom = [quad[3][k] + a * (quad[2][k] - quad[3][k]) for k in range(2)]
            p = [top[k] + b * (bottom[k] - top[k]) for k in range(2)]
            if distance_outside(hull, p) < margin:
                return True
    return False


def overlap(a, b, margin=0.0):
    return not (a[2] + margin < b[0] or b[2] + margin < a[0] or a[3] + margin < b[1] or
                b[3] + margin < a[1])


def check_layout():
    ok = True
    half_white = TAG_MM / 2.0 + 2 * TAG_MM / 8.0  # black square + 2-cell quiet zone
    spots = grid_points()
    for cam in CAMERAS:
        name, centre = cam[0], cam[1]
        grid = [project(cam, p) for p in spots]
        grid = [g for g in grid if g is not None and 0 <= g[0] < WIDTH and 0 <= g[1] < HEIGHT]
        grid_box = bbox(grid)
        hull = convex_hull(grid)
        lines = []
        boxes = {}
        for tag_id, (c, n) in sorted(TAGS.items()):
            to_cam = unit(sub(centre, c))
            angle = math.degrees(math.acos(max(-1.0, min(1.0, dot(to_cam, n)))))
            if angle >= 75.0:
                lines.append("%d: not seen (%.0f deg)" % (tag_id, angle))
                continue
            quad = [project(cam, p) for p in tag_corners(c, n, half_white)]
            if any(q is None for q in quad):
                lines.append("%d: behind" % tag_id)
                continue
            box = bbox(quad)
            border = min(box[0], box[1], WIDTH - 1 - box[2], HEIGHT - 1 - box[3])
            black = bbox([project(cam, p) for p in tag_corners(c, n, TAG_MM / 2.0)])
            size = min(black[2] - black[0], black[3] - black[1])
            lines.append("%d: %.0f deg, %.0f px, border %.0f px" % (tag_id, angle, size, border))
            if border < 20:
                print("  %s: tag %d leaves the image (border %.0f px)" % (name, tag_id, border))
                ok = False
                continue
            if quad_near_hull(quad, hull, 15.0):
                print("  %s: tag %d overlaps the laser grid" % (name, tag_id))
                ok = False
            boxes[tag_id] = box
        for a in boxes:
            for b in boxes:
                if a < b and overlap(boxes[a], boxes[b], 5.0):
                    print("  %s: tags %d and %d overlap" % (name, a, b))
                    ok = False
        print("%s (grid %.0f..%.0f x %.0f..%.0f px): %s" %
              (name, grid_box[0], grid_box[2], grid_box[1], grid_box[3], "; ".join(lines)))
    return ok


def module_design():
    return {
        "format": "opl.module_design",
        "version": 1,
        "description": "The module of examples/scene_verify_18mp.json: the prototype's two 11 x 11 "
                       "equal-angle sources (29 deg, 55 mm apart, looking along +X, as "
                       "scene_small_module.json) standing at x = 500 mm, the front of the "
                       "measuring volume, throwing their grids on the back wall 2 m ahead "
                       "(x = 2500 mm). Written by examples/python/make_verify_scene.py.",
        "sources": [
            {"name": name, "pattern": "equal_angle", "beams_per_side": 11, "full_angle_deg": 29.0,
             "wavelength_nm": 658.0, "origin_mm": [MODULE_X, y, 0.0],
             "rotation_xyz_rad": [0.0, 0.0, 0.0], "beam_error_mrad": 0.3, "beam_error_seed": seed}
            for name, y, seed in (("A", 27.5, 7), ("B", -27.5, 8))
        ],
        "surface": {"type": "plane", "point_mm": [WALL_X, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]},
        "spot_noise_mm": [0.110, 0.073, 0.073],
    }


def scene():
    cameras = []
    for k, (name, centre, look_at, roll) in enumerate(CAMERAS):
        cameras.append({
            "name": name, "width_px": WIDTH, "height_px": HEIGHT,
            "intrinsics": {"fx": F + 2.0 * k, "fy": F + 2.0 * k, "cx": 2451.5 + 3.0 * k,
                           "cy": 1844.5 - 2.0 * k, "k1": -0.05 - 0.005 * k, "k2": 0.01,
                           "p1": 0.0005, "p2": -0.0003, "k3": 0.0},
            "pose": {"center_mm": centre, "look_at_mm": look_at, "roll_deg": roll}})
    placements = [{"id": i, "center_mm": c, "normal": [round(x, 12) for x in n],
                   "up": [round(x, 12) for x in up_in_plane(n)]}
                  for i, (c, n) in sorted(TAGS.items())]
    checks = []
    for name, a, b in CHECKS:
        length = norm(sub(TAGS[a][0], TAGS[b][0]))
        checks.append({"name": name, "tag_1": a, "tag_2": b, "length_mm": round(length, 9),
                       "length_sigma_mm": CHECK_SIGMA_MM})
    bar_length = norm(sub(TAGS[BAR[0]][0], TAGS[BAR[1]][0]))
    shots = [{"camera": c[0], "file": "%s_%s.png" % (c[0], laser), "lasers": [laser], "slice": 0}
             for laser in ("A", "B") for c in CAMERAS]
    return {
        "format": "opl.scene",
        "version": 1,
        "description": "The acceptance test of docs/verify.md (VDI/VDE 2634-1, ISO 10360-13) in "
                       "the virtual lab: a measuring volume of 2 x 2 x 1.5 m (x 500..2500, y "
                       "-1000..1000, z -750..750 mm) seen by six 18 MP cameras (4912 x 3684, fx "
                       "4000 px); 140 mm tags on the back wall (0, 1, 2 the frame), on posts at "
                       "the front corners, on side-wall brackets and floor wedges; ten check "
                       "lengths between them (space diagonals, edges, a floor diagonal); a "
                       "1200 mm scale bar (tags 20, 21) as the artifact; the module at the "
                       "front throwing its grids on the back wall. Written by "
                       "examples/python/make_verify_scene.py.",
        "cameras": cameras,
        "tags": {"family": "tag36h11", "size_mm": TAG_MM, "placements": placements},
        "frame": {"origin_tag": 0, "axis_tag": 1, "plane_tag": 2},
        "artifact": {"tag_1": BAR[0], "tag_2": BAR[1], "length_mm": round(bar_length, 9),
                     "length_sigma_mm": 0.01},
        "module": os.path.basename(MODULE),
        "spots": {"diameter_mm": 6.0, "peak_fraction": 0.6, "speckle_contrast": 0.3,
                  "speckle_grain_px": 1.5},
        "image": {"bit_depth": 8, "background_level": 0.25, "black_level": 0.05,
                  "white_level": 0.6, "blur_sigma_px": 0.6, "read_noise": 0.004,
                  "gain_e_per_dn": 20.0, "subpixels_per_axis": 2},
        "seed": 1,
        "check_lengths": checks,
        "shots": shots,
    }


def main():
    s = scene()
    lo = [min(c[i] for c, _ in TAGS.values()) for i in range(3)]
    hi = [max(c[i] for c, _ in TAGS.values()) for i in range(3)]
    diagonal = norm(sub(hi, lo))
    print("tag box %s .. %s mm, space diagonal %.1f mm, 2/3 of it %.1f mm" %
          (lo, hi, diagonal, 2.0 * diagonal / 3.0))
    for c in s["check_lengths"]:
        print("  %-13s tags %2d-%2d  %9.3f mm" % (c["name"], c["tag_1"], c["tag_2"], c["length_mm"]))
    print("  bar           tags %2d-%2d  %9.3f mm" % (BAR[0], BAR[1], s["artifact"]["length_mm"]))
    if not check_layout():
        print("layout refused: nothing written")
        return 1
    for path, doc in ((MODULE, module_design()), (SCENE, s)):
        with open(path, "w") as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
        print("wrote " + os.path.relpath(path))
    return 0


if __name__ == "__main__":
    sys.exit(main())
