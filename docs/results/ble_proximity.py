#!/usr/bin/env python3
"""BLE proximity on the IPIN 2023 logfiles: is a strong beacon reading a position hint?

Standard library only; reads the data in place:

    python3 docs/results/ble_proximity.py [DIR, default $WIPDR_DATA/ipin2023]

Prints (1) the true distance from the phone (POSI interpolated) to the beacon position listed
in BLE_Locations.csv, by RSSI bin and by same / other floor, and per beacon for readings of
-72 dBm or more; (2) leave-one-route-out: each beacon (minor ID) placed at the median training
position of its readings at or above a threshold, the strongest such reading in the 4 s
before a POSI point taken as a fix, and that fix's error. docs/results/ipin.md quotes both.
The local frame is an equirectangular one about 49.4611 N 11.1110 E (error < 1 cm here).
"""
import collections
import glob
import gzip
import math
import os
import sys

# The data root: $WIPDR_DATA (relative to the repository), else ../shared/data beside it.
REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
DATA_ROOT = os.path.join(REPO, os.environ.get("WIPDR_DATA") or os.path.join("..", "shared", "data"))
DATA = sys.argv[1] if len(sys.argv) > 1 else os.path.join(DATA_ROOT, "ipin2023")
LAT0, LON0 = 49.4611, 11.1110


def local(lat, lon):
    return ((lon - LON0) * math.cos(math.radians(LAT0)) * 111320.0, (lat - LAT0) * 110540.0)


def beacons():
    out = {}
    with open(os.path.join(DATA, "BLE_Locations.csv")) as f:
        for line in f.read().splitlines()[1:]:
            if line.strip():
                name, lat, lon, floor = line.replace('"', "").split(",")
                out[int(name[3:])] = (local(float(lat), float(lon)), int(floor))
    return out


def walks():
    for path in sorted(glob.glob(os.path.join(DATA, "trials", "*.txt*"))):
        posi, ble = [], []
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "rt", errors="replace") as f:
            for line in f:
                if line.startswith("POSI;"):
                    p = line.split(";")
                    posi.append((float(p[1]), local(float(p[3]), float(p[4])), int(p[5])))
                elif line.startswith("BLE4;"):
                    p = line.split(";")
                    if len(p) > 7 and p[2] == "iBeacon":
                        ble.append((float(p[1]), int(p[7]), float(p[4])))
        posi.sort()
        if len(posi) >= 2:
            yield path.split("Trial")[1][:2], posi, ble


def at(posi, t):
    """Position and floor at `t` between POSI points of one floor, else None."""
    if t < posi[0][0] or t > posi[-1][0]:
        return None
    i = next(i for i in range(len(posi) - 1) if posi[i][0] <= t <= posi[i + 1][0])
    a, b = posi[i], posi[i + 1]
    if a[2] != b[2]:
        return None
    w = (t - a[0]) / max(b[0] - a[0], 1e-6)
    return (a[1][0] + w * (b[1][0] - a[1][0]), a[1][1] + w * (b[1][1] - a[1][1]), a[2])


def quantiles(v):
    v = sorted(v)
    n = len(v)
    return "n %5d  median %5.1f  p75 %5.1f  p90 %5.1f" % (n, v[n // 2], v[int(0.75 * n)], v[int(0.9 * n)])


def main():
    bea, ws = beacons(), list(walks())
    by_bin, by_beacon = collections.defaultdict(list), collections.defaultdict(list)
    for _, posi, ble in ws:
        for t, minor, rssi in ble:
            p = at(posi, t)
            if p is None or minor not in bea:
                continue
            (bx, by), bf = bea[minor]
            d = math.hypot(p[0] - bx, p[1] - by)
            by_bin[(int(rssi // 5) * 5, p[2] == bf)].append(d)
            if rssi >= -72:
                by_beacon[(minor, p[2])].append(d)
    print("distance (m) to the listed beacon by RSSI bin (dBm), phone on the beacon's floor or not")
    for (lo, same), d in sorted(by_bin.items()):
        print("  %4d..%4d  %-11s %s" % (lo, lo + 5, "same floor" if same else "other floor", quantiles(d)))
    print("readings >= -72 dBm: distance to the listed position, by beacon and phone floor")
    for (minor, floor), d in sorted(by_beacon.items()):
        print("  BLE%d (listed floor %d), phone on %d: %s" % (minor, bea[minor][1], floor, quantiles(d)))
    print("leave-one-route-out: beacon at the median training position of its strong readings")
    for threshold in (-75, -70, -65):
        errors, points = [], 0
        for route in sorted({w[0] for w in ws}):
            seen = collections.defaultdict(list)
            for r, posi, ble in ws:
                if r != route:
                    for t, minor, rssi in ble:
                        p = at(posi, t) if rssi >= threshold else None
                        if p:
                            seen[minor].append(p)
            place = {}
            for minor, ps in seen.items():
                floor = collections.Counter(p[2] for p in ps).most_common(1)[0][0]
                on = [p for p in ps if p[2] == floor]
                xs, ys = sorted(p[0] for p in on), sorted(p[1] for p in on)
                place[minor] = (xs[len(xs) // 2], ys[len(ys) // 2])
            for r, posi, ble in ws:
                if r != route:
                    continue
                for t, (x, y), _ in posi:
                    points += 1
                    near = [(rssi, m) for tt, m, rssi in ble
                            if t - 4 <= tt <= t and rssi >= threshold and m in place]
                    if near:
                        bx, by = place[max(near)[1]]
                        errors.append(math.hypot(bx - x, by - y))
        print("  >= %d dBm: a fix at %d of %d POSI points, error %s" % (
            threshold, len(errors), points, quantiles(errors) if errors else "-"))


if __name__ == "__main__":
    main()
