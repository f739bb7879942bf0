"""Tables of docs/results/fusion-synthetic.md: the example `synthetic_compare` of wipdr-fusion
(seeded synthetic walks; `cargo run --release -p wipdr-fusion --example synthetic_compare`)."""

from regenerate import table


def sections(runs):
    """The example's output split at its `## ` headings: {heading: body}."""
    out = runs.command(["cargo", "run", "--release", "-q", "-p", "wipdr-fusion",
                        "--example", "synthetic_compare"])
    parts, head = {}, None
    for line in out.splitlines():
        if line.startswith("## "):
            head = line[3:].strip()
            parts[head] = []
        elif head is not None:
            parts[head].append(line)
    return {h: "\n".join(b).strip("\n") for h, b in parts.items()}


def section(runs, starts):
    found = [b for h, b in sections(runs).items() if h.startswith(starts)]
    if len(found) != 1:
        raise SystemExit(f"synthetic_compare: no single section starting {starts!r}")
    return found[0]


@table("fusion-synthetic-correct-start")
def correct_start(runs):
    """20 synthetic walks, first fix correct: every scheme's shipped defaults and variants."""
    return section(runs, "Synthetic walks, first fix correct")


@table("fusion-synthetic-gross-start")
def gross_start(runs):
    """The same walks with a gross first fix (a start in a coverage gap)."""
    return section(runs, "Synthetic walks starting from a gross first fix")
