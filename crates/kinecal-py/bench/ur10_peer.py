#!/usr/bin/env python3
"""CPU time of a calibration from Python against the numpy/scipy baseline, in one run.

The baseline (../shared/bench/ur10_mdh/peer_baseline.py) writes a synthetic UR10 problem
(modified DH, position-only, 19 identifiable parameters) and times scipy's least_squares on its
solve alone. Here the same problem is calibrated from numpy arrays with the kinecal package
(`kinecal.calibrate`: the whole workflow, uncertainty and report included), timed the same way
(process CPU time, median of repeats). Needs the kinecal wheel (release build: `maturin build
--release` in crates/kinecal-py), numpy and scipy.

    python3 crates/kinecal-py/bench/ur10_peer.py [--sizes 1000,10000] [--repeat 5]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import kinecal

HERE = os.path.dirname(os.path.abspath(__file__))
BASELINE = os.path.join(HERE, "..", "..", "..", "..", "shared", "bench", "ur10_mdh",
                        "peer_baseline.py")


def load(path, robot):
    """A kinecal measurement CSV read with numpy: readings and positions."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    joints = sum(1 for c in header if c.startswith("v"))
    rows = np.loadtxt(path, delimiter=",", skiprows=1, usecols=range(2, 2 + joints + 3))
    return rows[:, :joints], rows[:, joints:joints + 3]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1000,10000")
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([sys.executable, BASELINE, "data", d, "--sizes", a.sizes], check=True,
                       capture_output=True)
        robot = kinecal.Robot.from_dh(os.path.join(d, "mdh_nominal.csv"), convention="modified",
                                      length_unit="mm", angle_unit="rad", name="UR10")
        with open(os.path.join(d, "est_ident.txt")) as f:
            estimate = f.read().strip()
        q, p = load(os.path.join(d, "val_1000.csv"), robot)
        held = kinecal.Measurements(robot, q, p)
        print(f"{'poses':>6} {'params':>6} {'numpy s':>9} {'kinecal s':>9} {'ratio':>7}"
              f" {'+validation s':>13} {'ratio':>7} {'held-out numpy mm':>18} {'kinecal mm':>11}")
        for n in sizes:
            peer = json.loads(subprocess.run(
                [sys.executable, BASELINE, "solve", d, "--n", str(n), "--mask", "ident",
                 "--repeat", "3"], check=True, capture_output=True, text=True).stdout)
            q, p = load(os.path.join(d, f"calib_{n}.csv"), robot)

            def timed(q=q, p=p, **kw):
                # Each call on Measurements of its own, built before the clock starts: a
                # Measurements keeps the sines of its readings for the next calibration on it,
                # which the peer's solve would not get from a repeat.
                fresh = [kinecal.Measurements(robot, q, p) for _ in range(a.repeat)]
                times = []
                for data in fresh:
                    t0 = time.process_time()
                    result = kinecal.calibrate(robot, data, estimate=estimate, **kw)
                    times.append(time.process_time() - t0)
                times.sort()
                return times[len(times) // 2], result

            # Like for like: the baseline's timed solve checks nothing; the second column adds
            # kinecal's check on the 1,000 held-out poses.
            alone, result = timed()
            checked, result = timed(validate=held)
            print(f"{n:>6} {len(result.estimated):>6} {peer['cpu_s']:>9.4f} {alone:>9.4f}"
                  f" {peer['cpu_s'] / alone:>7.1f} {checked:>13.4f} {peer['cpu_s'] / checked:>7.1f}"
                  f" {peer['held_out_mean_mm']:>18.5f}"
                  f" {result.validation['after']['mean_position']:>11.5f}")


if __name__ == "__main__":
    main()
