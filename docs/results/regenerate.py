#!/usr/bin/env python3
"""Rewrites the generated tables of docs/results/*.md from repository commands (`just results`).

A generated table sits between two HTML comments in a results document:

    <!-- table: ilc-pooled -->
    | scheme | causal mean / p95 | ... |
    | --- | --- | ... |
    <!-- /table -->

`ilc-pooled` names a recipe: a Python function in `docs/results/recipes/*.py` registered with
`@table("ilc-pooled")`. It receives a `Runs` object, runs the `wipdr` commands it needs
through it (`runs.wipdr_json(...)`, `runs.command(...)`; one run is shared by every table
that asks for the same arguments) and returns the block's markdown. Everything between the
two comments is replaced; the prose around them is not touched. A recipe is deterministic
(seeded, no timing) unless registered with `measured=True` (speed figures: rewritten by
`--measured` only and never compared by `--check`).

    docs/results/regenerate.py                  # run every recipe, rewrite the documents
    docs/results/regenerate.py --only ilc-      # recipes whose name starts with ilc-, or
    docs/results/regenerate.py --only floors.md #   every block of one document
    docs/results/regenerate.py --check          # rewrite nothing; exit 1 and show a diff
                                                #   when a block differs from its recipe
    docs/results/regenerate.py --list           # recipes, their documents and commands
    docs/results/regenerate.py --reuse          # reuse the JSON of an earlier run
                                                #   (target/results/), for editing recipes

Environment: WIPDR (the program, default target/release/wipdr; `just results` builds it),
WIPDR_DATA (the real data root, default ../shared/data). Standard library only.
"""

import argparse
import difflib
import hashlib
import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
RESULTS = ROOT / "docs" / "results"
WORK = ROOT / "target" / "results"
BLOCK = re.compile(
    r"(?P<open><!-- table: (?P<name>[A-Za-z0-9_.-]+) -->\n)(?P<body>.*?)(?P<close><!-- /table -->)",
    re.S,
)

RECIPES = {}


def table(name, measured=False):
    """Registers a recipe: `@table("name")` over `def f(runs) -> str` (the block's markdown)."""

    def register(function):
        if name in RECIPES:
            raise SystemExit(f"recipe {name!r} is registered twice")
        RECIPES[name] = (function, measured)
        return function

    return register


def data_root():
    """The real data root: $WIPDR_DATA, else ../shared/data beside the repository."""
    return Path(os.environ.get("WIPDR_DATA") or ROOT.parent / "shared" / "data")


def ilc_floors():
    """The five ILC 2.0 floors every ILC table is pooled over."""
    d = data_root() / "ilc20"
    return [str(d / s / f) for s, f in
            [("site1", "F1"), ("site1", "F2"), ("site2", "F1"), ("site2", "F2"), ("site2", "F3")]]


class Runs:
    """Runs commands once per distinct argument list and keeps their JSON under target/results/."""

    def __init__(self, reuse):
        self.reuse = reuse
        self.program = os.environ.get("WIPDR") or str(ROOT / "target" / "release" / "wipdr")
        self.done = {}
        WORK.mkdir(parents=True, exist_ok=True)

    def _key(self, argv):
        return hashlib.sha256("\0".join(argv).encode()).hexdigest()[:16]

    def command(self, argv, outputs=()):
        """Runs `argv` (a list; `wipdr` as argv[0] means the program) from the repository root
        unless an earlier call ran it; returns its stdout. `outputs` are files it writes,
        checked to exist afterwards."""
        argv = [self.program if a == "wipdr" else str(a) for a in argv]
        key = self._key(argv)
        if key in self.done:
            return self.done[key]
        log = WORK / f"{key}.stdout"
        if self.reuse and log.exists() and all(Path(o).exists() for o in outputs):
            out = log.read_text()
        else:
            print("  $", " ".join(shlex.quote(a) for a in argv), file=sys.stderr, flush=True)
            t0 = time.time()
            proc = subprocess.run(argv, cwd=ROOT, stdout=subprocess.PIPE, text=True)
            if proc.returncode != 0:
                raise SystemExit(f"command failed ({proc.returncode}): {' '.join(argv)}")
            print(f"    {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
            out = proc.stdout
            log.write_text(out)
        for o in outputs:
            if not Path(o).exists():
                raise SystemExit(f"command did not write {o}: {' '.join(argv)}")
        self.done[key] = out
        return out

    def wipdr_json(self, *args):
        """`wipdr ARGS... --json FILE` once per distinct ARGS; returns the parsed JSON."""
        argv = ["wipdr", *map(str, args)]
        path = WORK / f"{self._key(argv)}.json"
        self.command([*argv, "--json", str(path)], outputs=[path])
        return json.loads(path.read_text())


def load_recipes():
    for path in sorted((RESULTS / "recipes").glob("*.py")):
        spec = importlib.util.spec_from_file_location(f"recipes.{path.stem}", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)


def blocks():
    """(document, recipe name) for every generated block, in document order."""
    found = []
    for doc in sorted(RESULTS.glob("*.md")):
        for m in BLOCK.finditer(doc.read_text()):
            found.append((doc, m.group("name")))
    return found


def selected(doc, name, only):
    return not only or any(name.startswith(o) or doc.name == o for o in only)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", action="append", default=[], help="recipe-name prefix or document file name")
    parser.add_argument("--check", action="store_true", help="compare, rewrite nothing")
    parser.add_argument("--measured", action="store_true", help="also rewrite the speed (measured) tables")
    parser.add_argument("--list", action="store_true")
    parser.add_argument("--reuse", action="store_true", help="reuse target/results/ outputs of an earlier run")
    args = parser.parse_args()
    sys.path.insert(0, str(RESULTS))
    sys.path.insert(1, str(RESULTS / "recipes"))  # recipes may import helper modules there
    sys.modules.setdefault("regenerate", sys.modules[__name__])
    load_recipes()

    found = blocks()
    unknown = sorted({f"{d.name}: {n}" for d, n in found if n not in RECIPES})
    if unknown:
        raise SystemExit("blocks with no recipe: " + ", ".join(unknown))
    orphans = sorted(set(RECIPES) - {n for _, n in found})
    if orphans:
        print("recipes with no block (not run): " + ", ".join(orphans), file=sys.stderr)
    if args.list:
        for doc, name in found:
            function, measured = RECIPES[name]
            doc_line = (function.__doc__ or "").strip().split("\n")[0]
            print(f"{doc.name:24} {name:28} {'measured ' if measured else ''}{doc_line}")
        return 0

    runs = Runs(args.reuse)
    differ = 0
    for doc in sorted({d for d, n in found if selected(d, n, args.only)}):
        text = doc.read_text()

        def replace(m):
            nonlocal differ
            name = m.group("name")
            function, measured = RECIPES[name]
            if not selected(doc, name, args.only) or (measured and not args.measured):
                return m.group(0)
            print(f"{doc.name}: {name}", file=sys.stderr, flush=True)
            body = function(runs).strip("\n") + "\n"
            if body != m.group("body"):
                differ += 1
                if args.check:
                    sys.stdout.writelines(difflib.unified_diff(
                        m.group("body").splitlines(True), body.splitlines(True),
                        f"{doc.name} [{name}] committed", f"{doc.name} [{name}] regenerated"))
            return m.group("open") + body + m.group("close")

        new = BLOCK.sub(replace, text)
        if not args.check and new != text:
            doc.write_text(new)
    if args.check:
        print(f"{differ} block(s) differ" if differ else "every selected block matches", file=sys.stderr)
        return 1 if differ else 0
    print(f"{differ} block(s) rewritten", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
