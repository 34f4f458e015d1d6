#!/bin/bash
# Submit a cohort as a Slurm job array, then the cohort summary once every array task has ended.
#
#   examples/submit-slurm.sh COHORT.toml [SHARDS] [-- SBATCH OPTIONS...]
#
# SHARDS defaults to one array task per CASES_PER_SHARD (50) cases, counted with `destair list`.
# Options after `--` go to the array's sbatch (e.g. --partition=short --time=04:00:00 --mem=8G
# --cpus-per-task=4); they override the defaults in slurm-array.sbatch. The summary job gets its
# own small allocation (SUMMARY_TIME, SUMMARY_MEM) and log. DESTAIR names the binary.
set -euo pipefail
usage="usage: $0 COHORT.toml [SHARDS] [-- SBATCH OPTIONS...]"
here="$(cd "$(dirname "$0")" && pwd)"
config="${1:?$usage}"
shift
shards=""
if [[ $# -gt 0 && "$1" != "--" ]]; then
    shards="$1"
    shift
fi
if [[ $# -gt 0 && "$1" == "--" ]]; then
    shift
fi
destair="${DESTAIR:-destair}"
# Fails (exit 2) with the reason when the config finds no cases or is wrong.
"$destair" check "$config" > /dev/null
if [[ -z "$shards" ]]; then
    n_cases=$("$destair" list "$config" | wc -l)
    per="${CASES_PER_SHARD:-50}"
    shards=$(( (n_cases + per - 1) / per ))
    (( shards >= 1 )) || shards=1
fi
if ! [[ "$shards" =~ ^[1-9][0-9]*$ ]]; then
    echo "$usage (SHARDS must be a positive number, got '$shards')" >&2
    exit 2
fi
array=$(sbatch --parsable --array="0-$(( shards - 1 ))" "$@" \
    --export=ALL,DESTAIR="$destair" "$here/slurm-array.sbatch" "$config")
array="${array%%;*}"
summary=$(sbatch --parsable --dependency="afterany:${array}" --job-name=destair-summary \
    --cpus-per-task=1 --mem="${SUMMARY_MEM:-2G}" --time="${SUMMARY_TIME:-00:30:00}" \
    --output=destair-summary-%j.log \
    --wrap "\"$destair\" summarize --config \"$config\"")
echo "submitted array ${array} (${shards} tasks) and summary job ${summary%%;*}"
