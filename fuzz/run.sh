#!/usr/bin/env bash
# Runs softfem's cargo-fuzz targets for a bounded time each and fails on any crash (a panic is a
# broken promise: see fuzz/README.md). Used by .ci/run; runnable by hand from anywhere:
#   fuzz/run.sh                    # every target, 60 s each (CI: 30 s each, 8 x 30 s = 240 s)
#   fuzz/run.sh 10 svd_contract    # one target, 10 s
# Installs the nightly toolchain (minimal profile) and cargo-fuzz if they are missing.
# Replays the inputs kept under fuzz/regressions/<target>/ first, then fuzzes from the seeds of
# fuzz/corpus/<target>/ plus what earlier runs found (target/fuzz-corpus/<target>/, not
# committed). Prints libFuzzer's final "#N DONE ... exec/s" line per target and a summary.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."

seconds="${1:-60}"
shift || true
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
    targets=(tetgen_reader gmsh_reader obj_reader voxel_embed body mesh_kernels svd_contract stepper)
fi

if ! cargo +nightly --version >/dev/null 2>&1; then
    rustup toolchain install nightly --profile minimal
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    cargo install cargo-fuzz --locked
fi
cargo +nightly fuzz --version
cargo fmt --check --manifest-path fuzz/Cargo.toml

# No sanitizer: the library's only `unsafe` is SSE intrinsics on registers (src/lanes_sse*.rs),
# which AddressSanitizer has nothing to check in, and it would halve the executions per minute.
# cargo-fuzz builds optimised with debug assertions and overflow checks on.
fuzz=(cargo +nightly fuzz)
options=(--sanitizer none)
"${fuzz[@]}" build "${options[@]}"

declare -A dictionary=([tetgen_reader]=$PWD/fuzz/dict/tetgen.dict)
# The targets of the std helpers run them with a 1 MiB budget (fuzz/src/voxel_checks.rs) on
# inputs of a few kilobytes: 512 MB is far above what they may use.
declare -A rss_limit_mb=([gmsh_reader]=512 [obj_reader]=512 [voxel_embed]=512 [body]=512)
failed=()
summary=()
log_dir=target/fuzz-logs
mkdir -p "$log_dir"
for target in "${targets[@]}"; do
    regressions=(fuzz/regressions/"$target"/*)
    if [[ -e ${regressions[0]} ]]; then
        echo "=== $target: replaying ${#regressions[@]} kept input(s) from fuzz/regressions/$target"
        if ! "${fuzz[@]}" run "${options[@]}" "$target" "${regressions[@]}" -- -runs=1; then
            failed+=("$target (a kept regression input fails)")
        fi
    fi

    echo "=== $target: fuzzing for $seconds s"
    corpus="$PWD/target/fuzz-corpus/$target"
    mkdir -p "$corpus"
    # A memory limit per target: an input that makes the library allocate without bound (an
    # abort on allocation, or a buffer sized from the input without a check that the kernel
    # lets through and the library then fills) is a crash.
    args=(-max_total_time="$seconds" -timeout=30 -rss_limit_mb="${rss_limit_mb[$target]:-2048}"
        -print_final_stats=1)
    if [[ -n ${dictionary[$target]:-} ]]; then
        args+=(-dict="${dictionary[$target]}")
    fi
    log="$log_dir/$target.log"
    status=0
    "${fuzz[@]}" run "${options[@]}" "$target" "$corpus" "$PWD/fuzz/corpus/$target" -- "${args[@]}" \
        2>&1 | tee "$log" || status=$?
    done_line=$(grep -E '^#[0-9]+[[:space:]]+DONE' "$log" | tail -n 1 || true)
    if [[ $status -ne 0 ]]; then
        failed+=("$target (exit status $status; the crashing input is under fuzz/artifacts/$target/)")
        last_line=$(grep -E '^#[0-9]+[[:space:]]' "$log" | tail -n 1 || true)
        summary+=("$target: FAILED, stopped at a crash after ${last_line:-the first input}")
        # What broke and the input that broke it, kept for the summary at the end: CI shows
        # only the tail of the output, and its artifacts are lost with the machine.
        panic_lines=$(grep -E -A4 'panicked at' "$log" | head -n 8 || true)
        if [[ -z $panic_lines ]]; then
            panic_lines=$(grep -E 'ERROR: libFuzzer|SUMMARY: libFuzzer' "$log" | head -n 2 || true)
        fi
        summary+=("  ${panic_lines:-(no panic message in $log)}")
        artifact=$(grep -oE 'Test unit written to [^ ]+' "$log" | tail -n 1 | cut -d' ' -f5 || true)
        if [[ -n $artifact && -f $artifact ]]; then
            summary+=("  input $artifact, base64 (replay: base64 -d > crash, then the README's replay command):")
            summary+=("  $(base64 -w 0 "$artifact")")
        fi
    else
        summary+=("$target: ${done_line:-(no DONE line)}")
    fi
done

echo
echo "=== fuzzing summary ($seconds s per target)"
printf '%s\n' "${summary[@]}"
if [[ ${#failed[@]} -gt 0 ]]; then
    echo "fuzzing failed:" >&2
    printf '  %s\n' "${failed[@]}" >&2
    exit 1
fi
