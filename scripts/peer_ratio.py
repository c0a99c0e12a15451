#!/usr/bin/env python3
"""CPU time of kinecal against the numpy/scipy baseline of ../shared/bench/ur10_mdh, in one run.

The baseline writes a synthetic UR10 (modified DH, position-only) problem in kinecal's formats
and times scipy's least_squares (LM) on its solve alone; kinecal is timed on its whole process
(start, reading and fingerprinting the files, the same parameter list, solving, the uncertainty,
the report written to disk), once as the baseline is timed (the calibration alone; ratio
"solve") and once with `--validate` on the 1,000 held-out poses (reading and checking them too;
ratio "+val"), which also gives kinecal's held-out error. Prints, for 1,000 and 10,000 poses and
for the well-conditioned (19 identifiable parameters) and rank-deficient (all 24) problems, the
CPU times, the ratios and both held-out errors. Each figure is the median of several runs;
single-threaded BLAS for numpy (OPENBLAS_NUM_THREADS=1, as the baseline asks).

Run from the repository root, with numpy and scipy installed:
    python3 scripts/peer_ratio.py            # all four problems (scipy takes minutes on the last)
    python3 scripts/peer_ratio.py --quick    # without 10,000 poses x 24 parameters
"""

import json
import os
import resource
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BASELINE = os.path.join(ROOT, "..", "shared", "bench", "ur10_mdh", "peer_baseline.py")


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)


def kinecal_cpu(cmd, runs):
    """Median CPU seconds (user + system) of `runs` runs of `cmd`."""
    times = []
    for _ in range(runs):
        c0 = child_cpu()
        run(cmd)
        times.append(child_cpu() - c0)
    times.sort()
    return times[len(times) // 2]


def main():
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    run(["cargo", "build", "--release", "-q", "-p", "kinecal-cli"], cwd=ROOT)
    kinecal = os.path.join(ROOT, "target", "release", "kinecal")
    sizes = [1000, 10000]
    with tempfile.TemporaryDirectory() as d:
        run([sys.executable, BASELINE, "data", d, "--sizes", ",".join(map(str, sizes))])
        run([kinecal, "import", "dh", "--convention", "modified", os.path.join(d, "mdh_nominal.csv"),
             "--length-unit", "mm", "--angle-unit", "rad", "--out", os.path.join(d, "ur10.toml")])
        print(f"{'poses':>6} {'problem':<8} {'params':>6} {'numpy s':>9} {'kinecal s':>9} {'solve':>7}"
              f" {'+val s':>8} {'+val':>6} {'held-out numpy mm':>18} {'kinecal mm':>11}")
        for n in sizes:
            for mask in ["ident", "full"]:
                if "--quick" in sys.argv and n == 10000 and mask == "full":
                    continue
                peer = json.loads(run([sys.executable, BASELINE, "solve", d, "--n", str(n), "--mask", mask,
                                       "--repeat", "5"]).stdout)
                est = open(os.path.join(d, f"est_{mask}.txt")).read().strip()
                calibrate = [kinecal, "calibrate", "--robot", os.path.join(d, "ur10.toml"),
                             "--data", os.path.join(d, f"calib_{n}.csv"), "--estimate", est, "--quiet",
                             "--report", os.path.join(d, "r.json")]
                solve = kinecal_cpu(calibrate, 7)
                validated = kinecal_cpu(calibrate + ["--validate", os.path.join(d, "val_1000.csv")], 7)
                rep = json.load(open(os.path.join(d, "r.json")))
                held = rep["validation"]["after"]["mean_position"]
                print(f"{n:>6} {mask:<8} {peer['parameters']:>6} {peer['cpu_s']:>9.4f} {solve:>9.4f}"
                      f" {peer['cpu_s'] / solve:>7.1f} {validated:>8.4f} {peer['cpu_s'] / validated:>6.1f}"
                      f" {peer['held_out_mean_mm']:>18.5f} {held:>11.5f}")


if __name__ == "__main__":
    main()
