# Floor hits, EvAAL, mean and the worst time a walk spent on a wrong floor per scheme, from a
# `wipdr eval --json` document: `python3 docs/results/wrong_floor.py run.json`. The worst
# time follows wipdr_eval::scoring::WalkScore::longest_wrong_floor_ms (from the first
# waypoint of a run scored on a wrong floor to the next one scored right), for documents of
# builds whose table does not print it yet (docs/results/floors.md's "before" column).
import json, sys, collections
doc = json.load(open(sys.argv[1]))
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
