"""Per-sample cost of `Positioner.push_*` called from Python (the binding's overhead).

    python python/examples/push_cost.py [FLOOR_DIR] [--repeat 5]

The walk and model of `cargo bench -p wipdr-benches --bench positioner`: the longest walk of
the floor (default ILC site1/F1 under $WIPDR_DATA, else ../shared/data, when it exists; else
fixtures/sim/F1), the radio
map and PDR calibration of its protocol fold (default config), a fresh Positioner per run,
every raw sample pushed one at a time in stream order (the samples are put in order once,
before timing; the Positioner is built before timing too). Prints the best of `--repeat`
runs of the push loop, whole walk and per sample, per scheme, and the same loop calling a
no-op Python method (the cost of the Python loop and call alone). Compare with the Rust
bench's per-sample figure on the same walk and model (docs/results/positioner.md): the
difference is the binding's overhead.
"""

import argparse
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "python" / "tests"))

import wipdr  # noqa: E402
from streams import push_items, stream_order  # noqa: E402


def main(argv=None):
    env = os.environ.get("WIPDR_DATA")
    root = REPO / env if env else REPO.parent / "shared" / "data"
    real = root / "ilc20" / "site1" / "F1"
    default = real if real.is_dir() else REPO / "fixtures" / "sim" / "F1"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("floor", nargs="?", default=str(default))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--schemes", default="ekf,pmf")
    args = ap.parse_args(argv)

    floor = wipdr.read_floor(args.floor)
    walks = floor.walks
    index = max(range(len(walks)), key=lambda i: walks[i].duration_s)
    walk = walks[index]
    folds = floor.folds()
    training = wipdr.Floor([w for w, f in zip(walks, folds) if f != folds[index]], plan=floor.plan, name=floor.name)
    radio_map = wipdr.RadioMap.from_walks(training)
    items = stream_order(walk)
    n = len(items)
    print(f"{floor.name}: walk {walk.id} ({walk.duration_s:.0f} s, {n} samples, {len(walk.scans)} scans), map {len(radio_map)} points")

    # The Python side alone: the same loop calling a no-op method, for the floor of any call.
    class Null:
        def push_rotation_vector(self, t, x, y, z):
            return None

        push_gyroscope = push_magnetometer = push_accelerometer = push_rotation_vector

        def push_pressure(self, t, hpa):
            return None

        def push_scan(self, t, entries):
            return None

    best = min(_timed(lambda: push_items(Null(), items)) for _ in range(args.repeat))
    print(f"{'python loop, no-op calls':<28} {best * 1e3:8.2f} ms  {best / n * 1e6:6.2f} us/sample")
    for scheme in args.schemes.split(","):
        times = []
        for _ in range(args.repeat):
            p = wipdr.Positioner(radio_map, scheme, floor_plan=floor.plan, stream_id=walk.id)
            times.append(_timed(lambda: push_items(p, items)))
        best = min(times)
        print(f"{'Positioner.push_* ' + scheme:<28} {best * 1e3:8.2f} ms  {best / n * 1e6:6.2f} us/sample")
    return 0


def _timed(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


if __name__ == "__main__":
    sys.exit(main())
