# Floor hits, EvAAL, mean and the worst time a walk spent on a wrong floor per scheme, from a
# `wipdr eval --json` document: `python3 docs/results/wrong_floor.py run.json`. The worst
# time follows wipdr_eval::scoring::WalkScore::longest_wrong_floor_ms (from the first
# waypoint of a run scored on a wrong floor to the next one scored right), for documents of
# builds whose table does not print it yet (docs/results/floors.md's "before" column).
# `--walks SCHEME` also lists, for that scheme, every walk with a waypoint scored on a wrong
# floor: its floor, the points on a wrong floor of its scored points, and the floor offsets.
import json, sys, collections
args = sys.argv[1:]
walks_of = None
if "--walks" in args:
    i = args.index("--walks")
    walks_of = args[i + 1]
    del args[i:i + 2]
doc = json.load(open(args[0]))
worst = {}
for w in doc["walks"]:
    run = None; best = 0; errs = w["errors"]
    for t, m, fe in errs:
        if fe != 0:
            if run is None: run = t
        elif run is not None:
            best = max(best, t - run); run = None
    if run is not None and errs:
        best = max(best, errs[-1][0] - run)
    s = w["scheme"]
    if s not in worst or best > worst[s][0]:
        worst[s] = (best, w["walk"])
for s in doc["schemes"]:
    p = doc["pooled"][s]
    fh = p.get("floor_hit_rate")
    print(f"{s:6} floors {100*fh:.1f} %  evaal {p.get('evaal') or float('nan'):.2f}  mean {p['mean']:.2f}  worst wrong floor {worst[s][0]/1000:.1f} s ({worst[s][1]})")
if walks_of is not None:
    rows = []
    for w in doc["walks"]:
        if w["scheme"] != walks_of:
            continue
        offsets = [fe for _, _, fe in w["errors"]]
        wrong = sum(1 for fe in offsets if fe != 0)
        if wrong:
            rows.append((wrong, w["floor"], w["walk"], len(offsets), sorted(set(o for o in offsets if o))))
    total = sum(r[0] for r in rows)
    print(f"\n{walks_of}: {total} points on a wrong floor in {len(rows)} walks")
    for wrong, floor, walk, n, offs in sorted(rows, reverse=True):
        print(f"  {floor}  {walk}  {wrong} of {n} points  offsets {offs}")
