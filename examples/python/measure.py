#!/usr/bin/env python3
"""Measure the scale factor of a scene from its laser spots, with the opl module.

    python3 examples/python/measure.py --calibration examples/prototype_calibration.json \
        --spots examples/prototype_spots.csv [--apply cloud.ply --out cloud_mm.ply]

What opl_measure --spots does, as a script to build on: read the module
calibration and the spots (sorted or not), locate every source, print s with
its uncertainty and each source's origin and residuals, and optionally scale a
point file. docs/python.md.
"""
import argparse
import sys

import numpy as np

import opl


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration", required=True, help="module calibration JSON")
    parser.add_argument("--spots", required=True, help="spots CSV ([source,beam,]x,y,z[,sx,sy,sz])")
    parser.add_argument("--apply", help="point file to scale by s (PLY, XYZ or points CSV)")
    parser.add_argument("--out", help="where --apply writes the scaled points")
    args = parser.parse_args()
    if bool(args.apply) != bool(args.out):
        parser.error("--apply and --out go together")

    try:
        calibration = opl.read_module_calibration(args.calibration)
        spots = opl.read_spots_csv(args.spots)
        # The options opl_measure uses (wrong spots are flagged as outliers and left
        # out); opl.MeasureOptions() holds the locate and identify options to change.
        report = opl.measure_scale(calibration, spots, opl.MeasureOptions())
    except opl.Error as e:  # the message names the file, the line and the field
        print(f"measure.py: {e}", file=sys.stderr)
        return 1

    print(f"{len(spots)} spots, {int(spots.assigned.sum())} with source and beam")
    for name, located in report.sources:
        sigma = np.sqrt(np.diag(located.origin_covariance))
        print(f"source {name}: origin {np.array2string(located.origin, precision=4)} "
              f"+- {np.array2string(sigma, precision=4)} (scene units), "
              f"{located.num_inliers}/{located.num_spots} inliers, "
              f"RMS {located.rms_residual_rad * 1e6:.1f} urad, outliers {located.outlier_beam_ids()}")
    for length in report.scale.lengths:
        print(f"L {length.from_source}-{length.to_source}: photo {length.photo:.5f} +- {length.u_photo:.5f}, "
              f"calibrated {length.cal_mm:.5f} mm -> s = {length.scale:.6f}")
    print(f"s = {report.s:.6f} +- {report.u_s:.6f} mm per scene unit (k = 1), "
          f"{report.u_s / report.s * 1e6:.0f} ppm")

    if args.apply:
        try:
            summary = opl.scale_point_file(args.apply, args.out, report.s)
        except opl.Error as e:
            print(f"measure.py: {e}", file=sys.stderr)
            return 1
        print(summary.brief_report())
    return 0


if __name__ == "__main__":
    sys.exit(main())
