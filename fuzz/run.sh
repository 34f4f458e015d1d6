#!/usr/bin/env bash
# Builds one fuzz target with libFuzzer's coverage instrumentation on the stable toolchain (the
# flags `cargo fuzz build -O -a -s none` passes: no sanitizer, debug assertions and overflow
# checks on) and runs it for SECONDS under an address-space limit, as clusters set one: any
# input that makes destair allocate beyond it aborts, and libFuzzer reports that as a crash.
#
#   fuzz/run.sh TARGET SECONDS [ADDRESS_SPACE_MB] [-- more libFuzzer flags]
#
# TARGET is one of mesh_file, label_map, case, config. The corpus grows in
# fuzz/corpus/TARGET (kept between runs, not committed), starting from the small files in
# fuzz/seeds/TARGET where there are some; a crashing input is written to fuzz/artifacts/TARGET/.
# Prints libFuzzer's final statistics (executions).
set -euo pipefail
cd "$(dirname "$0")"
target=${1:?target}
seconds=${2:?seconds}
limit_mb=${3:-4096}
shift $(( $# < 3 ? $# : 3 ))
[ "${1:-}" = "--" ] && shift
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
export CARGO_TARGET_DIR="$PWD/target"
# An explicit --target keeps the flags off build scripts and proc macros, as cargo fuzz does.
host=$(rustc -vV | sed -n 's/^host: //p')
cargo build --locked --release --target "$host" --bin "$target" --quiet
mkdir -p "corpus/$target" "artifacts/$target"
# ulimit -v is in KiB; libFuzzer's own RSS limit is kept off (the address-space limit is the
# one being tested) and each input gets 60 s before it counts as a hang.
log="artifacts/$target/last-run.log"
set +e
(
    ulimit -v $((limit_mb * 1024))
    seeds=()
    [ -d "seeds/$target" ] && seeds=("seeds/$target")
    exec "target/$host/release/$target" "corpus/$target" "${seeds[@]}" \
        -artifact_prefix="artifacts/$target/" -max_total_time="$seconds" \
        -rss_limit_mb=0 -malloc_limit_mb=0 -timeout=60 -print_final_stats=1 "$@"
) > "$log" 2>&1
status=$?
set -e
echo "fuzz $target, ${seconds} s under ulimit -v ${limit_mb} MB:"
grep -E "^(Done [0-9]+ runs|stat::number_of_executed_units)" "$log" || true
if [ "$status" -ne 0 ]; then
    echo "fuzz $target failed (exit $status); the end of $log:"
    tail -n 60 "$log"
fi
exit "$status"
