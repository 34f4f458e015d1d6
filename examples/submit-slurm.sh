#!/bin/bash
# Submit the array, then the cohort summary once every array task has ended.
set -euo pipefail
array=$(sbatch --parsable examples/slurm-array.sbatch)
sbatch --dependency=afterany:"${array}" --job-name=destair-summary \
    --wrap "destair summarize out --config cohort.toml"
