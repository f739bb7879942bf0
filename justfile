# wipdr shortcuts (cargo commands underneath). `just --list` shows them.

# The real data root: $WIPDR_DATA, else ../shared/data beside the repository (README, "Real data").
data := env_var_or_default("WIPDR_DATA", "../shared/data")
floors := data + "/ilc20/site1/F1 " + data + "/ilc20/site1/F2 " + data + "/ilc20/site2/F1 " + data + "/ilc20/site2/F2 " + data + "/ilc20/site2/F3"

# The demo on the embedded fixtures (the README's first command).
demo:
    cargo run --release --bin wipdr -- demo

# All tests (the README's second command).
test:
    cargo test --workspace

# fmt check and clippy as CI runs them.
lint:
    cargo fmt --all -- --check
    cargo clippy --workspace --all-targets -- -D warnings

# Every relative markdown link and cited docs/, crates/, tools/, benches/ path resolves (under 1 s).
check-links:
    python3 .ci/check-links

# Everything CI runs.
ci:
    bash .ci/run

# Rewrite the generated tables of docs/results/ from their commands (docs/results/regenerate.py):
# `just results`, `just results --check` (empty diff or exit 1), `just results --only ilc-`.
results *args:
    cargo build --release -p wipdr
    python3 docs/results/regenerate.py {{args}}

# Criterion benchmarks (all, or one: `just bench matchers`).
bench name="":
    cargo bench -p wipdr-benches {{ if name == "" { "" } else { "--bench " + name } }}

# The Positioner's speed against docs/results/positioner.md: fails when a scheme's cost a
# sample grew more than 25 % (run on a quiet machine).
bench-check:
    cargo bench -p wipdr-benches --bench positioner
    python3 benches/check_positioner.py

# Inspect the five real floors.
inspect:
    for f in {{floors}}; do cargo run --release --bin wipdr -- inspect $f; done

# Evaluate all schemes on the five real floors.
eval schemes="wifi,pdr,ekf,aekf,akf,rkf,arkf,aws,tcpf,pf,apf":
    cargo run --release --bin wipdr -- eval --data {{floors}} --schemes {{schemes}} --json docs/results/eval.json

# A parameter sweep over the five real floors.
sweep config out:
    cargo run --release --bin wipdr -- sweep --config {{config}} --data {{floors}} --out {{out}} --resume

# Fingerprint benchmarks on the nine public datasets.
fingerprint:
    cargo run --release --bin wipdr -- fingerprint-eval --dataset {{data}}/fingerprint/* --matcher nn --matcher wknn --json docs/results/fingerprint.json

# Regenerate the committed synthetic fixtures.
fixtures:
    cargo run --release --bin wipdr -- simulate --out fixtures/sim --seed 2026 --walks 10 --duration-s 90 --gross-error-rate 0.05

# The papers' tables on the five real floors (docs/results/papers.md): `just papers tables`,
# `just papers tune` (the tuning sweeps) or `just papers all`.
papers mode="tables":
    cargo build --release -p wipdr
    bash docs/results/papers.sh {{mode}}

# Load benchmark of `wipdr serve` (docs/results/serve.md): SCHEMES="ekf pmf" PHONES="..." DURATION=60.
load-test:
    bash benches/load/load-test.sh
