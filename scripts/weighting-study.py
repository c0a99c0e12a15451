#!/usr/bin/env python3
"""How rows with an instrument's sigmas should be weighted, on synthetic data with a model error.

Each data set is the IPA UR10 (its nominal robot from `kinecal dataset ipa-ur10`) with random
geometric errors (`kinecal simulate --perturb-std length=0.0005,angle=0.001`, m and rad), whose
positions then get an error no geometric model fits: a cyclic transmission error on every
joint's reading (`a sin(q + phi) + b sin(2 q + phi)`, a and b drawn at --cyclic rad) and a sag
of the z coordinate growing with the square of the horizontal reach (--sag, 1/m). A tracker at
(2, -1.5, 0) m gives each identification point a sigma per axis, `k * range * exp(N(0, 0.8))`
(k = --sigma-per-metre), a --wide-fraction of them instead about --wide-sigma; the noise is
drawn at those sigmas. The first --identify postures are identified on, the next --hold-out
postures (no noise) held out; every fit is `kinecal calibrate --estimate identifiable`, and the
figure is its held-out mean position error. Per data set, four fits:

  alone      the sigma columns, `--model-error none` (each row at its sigma);
  none       the same rows without sigma columns (uniform weights);
  auto       the sigma columns, the default model-error floor;
  baseline   with --baseline KINECAL, that build's default on the sigma columns (another rule).

    python3 scripts/weighting-study.py --regime tracker --sets 30 [--kinecal PATH]
        [--baseline OTHER_KINECAL] [--work DIR]

The regimes of docs/calibrate.md: `tracker` (sigmas far below the model error), `near` (sigmas
about the model error), `wide` (a tenth of the rows stated at 2 mm). Needs
../shared/data/ipa_ur10_tracker. Prints a line per data set and the means.
"""

import argparse
import csv
import json
import math
import os
import random
import statistics
import subprocess
import sys
import tempfile

REGIMES = {
    "tracker": dict(cyclic=3e-4, sag=2e-4, sigma_per_metre=1e-5, wide_fraction=0.0, wide_sigma=0.0),
    "near": dict(cyclic=3e-4, sag=2e-4, sigma_per_metre=5e-5, wide_fraction=0.0, wide_sigma=0.0),
    "wide": dict(cyclic=3e-4, sag=2e-4, sigma_per_metre=1e-5, wide_fraction=0.1, wide_sigma=2e-3),
}
TRACKER = (2.0, -1.5, 0.0)


def run(args):
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(args)}: exit {p.returncode}\n{p.stderr}")
    return p


def write(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def make(kinecal, robot, d, seed, n_id, n_val, cyclic, sag, sigma_per_metre, wide_fraction, wide_sigma):
    """Writes d/id_sigma.csv, d/id_plain.csv (the same without sigma columns) and d/held.csv."""
    raw = os.path.join(d, "raw.csv")
    run([kinecal, "simulate", "-q", "--robot", robot, "--postures", str(n_id + n_val),
         "--seed", str(seed), "--perturb-std", "length=0.0005,angle=0.001", "--position-only",
         "--out", raw])
    with open(raw) as f:
        rows = list(csv.DictReader(f))
    rng = random.Random(seed)
    a = [rng.gauss(0, cyclic) for _ in range(6)]
    b = [rng.gauss(0, cyclic) for _ in range(6)]
    phi = [rng.uniform(0, 2 * math.pi) for _ in range(6)]
    ident, plain, held, ratios = [], [], [], []
    for i, r in enumerate(rows):
        q = [float(r[f"v{j}"]) for j in range(1, 7)]
        # The readings as the controller reports them: off by a cyclic transmission error.
        read = [q[j] - a[j] * math.sin(q[j] + phi[j]) - b[j] * math.sin(2 * q[j] + phi[j])
                for j in range(6)]
        x, y, z = (float(r[k]) for k in "xyz")
        z -= sag * (x * x + y * y)
        row = {"posture": f"P{i}", **{f"v{j + 1}": repr(read[j]) for j in range(6)}}
        if i >= n_id:
            held.append({**row, "x": repr(x), "y": repr(y), "z": repr(z)})
            continue
        if rng.random() < wide_fraction:
            s = [wide_sigma * math.exp(rng.gauss(0, 0.3)) for _ in range(3)]
        else:
            reach = math.dist((x, y, z), TRACKER)
            s = [sigma_per_metre * reach * math.exp(rng.gauss(0, 0.8)) for _ in range(3)]
        m = [c + rng.gauss(0, sc) for c, sc in zip((x, y, z), s)]
        row.update(x=repr(m[0]), y=repr(m[1]), z=repr(m[2]))
        plain.append(dict(row))
        ident.append({**row, "sigma_x": repr(s[0]), "sigma_y": repr(s[1]), "sigma_z": repr(s[2])})
        ratios.extend(s)
    write(os.path.join(d, "id_sigma.csv"), ident)
    write(os.path.join(d, "id_plain.csv"), plain)
    write(os.path.join(d, "held.csv"), held)
    return ratios


def fit(kinecal, robot, d, data, extra=()):
    report = os.path.join(d, "report.json")
    run([kinecal, "calibrate", "-q", "--robot", robot, "--data", os.path.join(d, data),
         "--validate", os.path.join(d, "held.csv"), "--estimate", "identifiable",
         "--report", report, *extra])
    with open(report) as f:
        j = json.load(f)
    floor = [w["length_mm"] for w in j.get("warning_details", [])
             if w.get("warning") == "model_error_floor"]
    return j["validation"]["after"]["mean_position"] * 1e3, (floor or [None])[0]


def main():
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog="example: python3 scripts/weighting-study.py --regime near --sets 20 "
        "--baseline /tmp/kinecal-other-build",
    )
    ap.add_argument("--regime", choices=sorted(REGIMES), required=True)
    ap.add_argument("--sets", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--identify", type=int, default=300)
    ap.add_argument("--hold-out", type=int, default=2000)
    ap.add_argument("--kinecal", default="target/release/kinecal")
    ap.add_argument("--baseline", help="another kinecal build, its default rule compared")
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(__file__), "../../shared"))
    ap.add_argument("--work", help="folder for the files (default: a temporary one)")
    o = ap.parse_args()
    source = os.path.join(o.shared, "data", "ipa_ur10_tracker")
    if not os.path.isdir(source):
        sys.exit(f"{source}: not found (the IPA UR10 data set gives the robot)")
    work = o.work or tempfile.mkdtemp(prefix="kinecal-weighting-")
    robot_dir = os.path.join(work, "ipa")
    run([o.kinecal, "dataset", "-q", "ipa-ur10", source, "--out", robot_dir])
    robot = os.path.join(robot_dir, "ur10.toml")
    names = ["alone", "none", "auto"] + (["baseline"] if o.baseline else [])
    results = []
    for seed in range(o.first_seed, o.first_seed + o.sets):
        d = os.path.join(work, f"set{seed}")
        os.makedirs(d, exist_ok=True)
        sigmas = make(o.kinecal, robot, d, seed, o.identify, o.hold_out, **REGIMES[o.regime])
        got = {
            "alone": fit(o.kinecal, robot, d, "id_sigma.csv", ("--model-error", "none"))[0],
            "none": fit(o.kinecal, robot, d, "id_plain.csv")[0],
        }
        got["auto"], m = fit(o.kinecal, robot, d, "id_sigma.csv")
        if o.baseline:
            got["baseline"] = fit(o.baseline, robot, d, "id_sigma.csv")[0]
        s = sorted(sigmas)
        spread = ""
        if m:
            spread = f"  sigma / m {s[len(s) // 20] * 1e3 / m:.3f}-{s[-len(s) // 20] * 1e3 / m:.3f} (5-95 %), m {m:.4f} mm"
        print(f"set {seed}: " + "  ".join(f"{k} {got[k]:.6f}" for k in names) + spread, flush=True)
        results.append(got)
    print("mean held-out error (mm): " + "  ".join(
        f"{k} {statistics.mean(r[k] for r in results):.5f}" for k in names))
    if o.baseline:
        behind = sum(r["auto"] > r["baseline"] for r in results)
        print(f"auto behind baseline in {behind} of {len(results)}")


if __name__ == "__main__":
    main()
