#!/usr/bin/env bash
# Runs examples/Snakefile for real (snakemake from PyPI, --cores 2) over a generated cohort and
# checks that it produces exactly the outputs of `destair run` (timings.json aside).
set -euo pipefail
destair="$(pwd)/target/debug/destair"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install --quiet --disable-pip-version-check snakemake
cd "$work"
"$destair" phantom cohort --cases 4 --out cases > /dev/null
cp "$OLDPWD/config/demo.toml" cohort.toml
"$destair" run cohort.toml
mv out out-run
"$work/venv/bin/snakemake" -s "$OLDPWD/examples/Snakefile" --cores 2 --quiet \
    --config cohort=cohort.toml out=out destair="$destair"
diff -r -x timings.json out out-run
echo "snakemake: same outputs as destair run"
