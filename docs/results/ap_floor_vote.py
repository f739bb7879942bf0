#!/usr/bin/env python3
"""Whether Wi-Fi alone could give the floor of the ILC walks `wipdr eval` misses.

A floor classifier independent of wipdr's matcher: each scan votes with its K strongest APs,
each AP for the floor on which the *other* walks of the site heard it loudest (leave one walk
out: the walk's own readings never vote; with `--folds EVAL.json`, a `wipdr eval --json`
report of the site, leave the walk's whole fold out, as the evaluation does). Prints the share of scans voting for their walk's
floor and the walks voting worst, with the votes their APs gave. Used in docs/results/floors.md
("ILC sites as buildings").

    python3 docs/results/ap_floor_vote.py [SITE_DIR] [--k 3] [--worst 5] [--folds EVAL.json]

SITE_DIR defaults to $WIPDR_DATA/ilc20/site2 (WIPDR_DATA: ../shared/data).
"""

import argparse
import collections
import gzip
import json
import os
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]


def read_walks(site: pathlib.Path) -> dict:
    """walk id -> (floor folder, [scan: {bssid: strongest RSS}]); lines that do not parse are
    counted and skipped (the traces have a few)."""
    walks, skipped = {}, 0
    for floor in sorted(p for p in site.iterdir() if (p / "path_data_files").is_dir()):
        for path in sorted((floor / "path_data_files").glob("*.txt*")):
            opener = gzip.open if path.suffix == ".gz" else open
            scans = collections.OrderedDict()
            with opener(path, "rt", errors="replace") as f:
                for line in f:
                    if "\tTYPE_WIFI\t" not in line:
                        continue
                    parts = line.rstrip("\n").split("\t")
                    try:
                        t, bssid, rss = parts[0], parts[3], float(parts[4])
                    except (IndexError, ValueError):
                        skipped += 1
                        continue
                    scan = scans.setdefault(t, {})
                    scan[bssid] = max(rss, scan.get(bssid, rss))
            walks[path.name.split(".")[0]] = (floor.name, list(scans.values()))
    if skipped:
        print(f"{site}: {skipped} Wi-Fi lines skipped (unparsable)", file=sys.stderr)
    return walks


def main() -> int:
    data = pathlib.Path(os.environ.get("WIPDR_DATA", ROOT.parent / "shared" / "data"))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", nargs="?", type=pathlib.Path, default=data / "ilc20" / "site2")
    parser.add_argument("--k", type=int, default=3, help="strongest APs voting per scan")
    parser.add_argument("--worst", type=int, default=5, help="walks listed")
    parser.add_argument("--folds", type=pathlib.Path,
                        help="a `wipdr eval --json` report: leave each walk's fold out")
    args = parser.parse_args()
    fold = {}
    if args.folds:
        fold = {w["walk"]: w["fold"] for w in json.loads(args.folds.read_text())["walks"]}
    if not args.site.is_dir():
        print(f"{args.site}: not found (set WIPDR_DATA)", file=sys.stderr)
        return 2
    walks = read_walks(args.site)
    # AP -> walk -> (floor, loudest reading of the AP in that walk)
    loudest = collections.defaultdict(dict)
    for walk, (floor, scans) in walks.items():
        for scan in scans:
            for bssid, rss in scan.items():
                _, best = loudest[bssid].get(walk, (floor, -1e9))
                loudest[bssid][walk] = (floor, max(best, rss))

    def votes_of(walk: str, scan: dict) -> collections.Counter:
        votes = collections.Counter()
        for bssid, _ in sorted(scan.items(), key=lambda e: -e[1])[: args.k]:
            by_floor = {}
            for other, (floor, rss) in loudest[bssid].items():
                same = other == walk or (walk in fold and fold.get(other) == fold[walk])
                if not same and rss > by_floor.get(floor, -1e9):
                    by_floor[floor] = rss
            votes[max(by_floor, key=by_floor.get) if by_floor else "unheard elsewhere"] += 1
        return votes

    rows, hits, total = [], 0, 0
    for walk, (floor, scans) in walks.items():
        walk_hits, walk_scans, ap_votes = 0, 0, collections.Counter()
        for scan in scans:
            votes = votes_of(walk, scan)
            ap_votes += votes
            decided = [(n, f) for f, n in votes.items() if f != "unheard elsewhere"]
            if decided:
                walk_scans += 1
                walk_hits += max(decided)[1] == floor
        hits, total = hits + walk_hits, total + walk_scans
        if walk_scans:
            rows.append((walk_hits / walk_scans, walk, floor, walk_scans, dict(ap_votes)))
    print(f"{args.site.name}: {len(walks)} walks, {total} scans, {hits / max(total, 1):.1%} "
          f"vote for their walk's floor ({args.k} strongest APs, leave one "
          f"{'fold' if fold else 'walk'} out)")
    for share, walk, floor, n, votes in sorted(rows)[: args.worst]:
        print(f"  {walk} on {floor}: {share:.0%} of {n} scans; AP votes {votes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
