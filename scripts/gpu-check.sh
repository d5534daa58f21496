#!/usr/bin/env bash
# Everything a GPU machine should be asked, in one run (about 8 minutes on a 16-core machine;
# its default budgets bound it at 12), with every answer written into OUTDIR as it comes:
#
#   adapter.txt     the adapters wgpu sees, the one pycinder chose, nvidia-smi where present
#   suite.log       the test suite, one verdict line per test as it finishes (pytest -v); each
#                   test under a timeout of its own, the whole run under an outer one, so that a
#                   run stopped early still names every failure (failures.txt)
#   processes.log   the fork and process-pool tests (tests/test_processes.py), on their own
#   bench.log       pycinder bench: Stairs, 1000 bodies and 16 deforming bunnies, with Warp in
#   bench/          the same process (on CUDA where Warp sees a device; the CUDA rows are
#                   marked skipped where it does not)
#   repro.log       scripts/repro-warp-hang.py: the reported hang's case, with its diagnostics
#   summary.txt     each step's exit status and seconds; the failing tests
#
#   scripts/gpu-check.sh [--quick] OUTDIR [WHEELDIR]
#
# WHEELDIR: a folder of wheels (pycinder's and its dependencies') to install from, for a machine
# without a package index (pip --no-index --find-links). Without it the Python on PATH (or
# $PYTHON) must already have pycinder and its test extra.
# --quick: short budgets and a few test files, for a machine without a GPU (lavapipe), where
# the whole suite takes ten minutes on two cores.
# Budgets in seconds, each step's outer timeout: SUITE_S (240), PROCESSES_S (300: every deadline
# of tests/test_processes.py together, so that each test's verdict comes back even when all of
# them hang; they pass in well under a minute), BENCH_S (90), REPRO_S (60); a test's own: TEST_S
# (120).
set -uo pipefail

quick=0
if [[ ${1:-} == --quick ]]; then quick=1; shift; fi
if [[ $# -lt 1 || $# -gt 2 || ${1:-} == -* ]]; then
    sed -n '2,26p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
fi
out=$(mkdir -p "$1" && cd "$1" && pwd)
wheels=${2:-}
root=$(cd "$(dirname "$0")/.." && pwd)
py=${PYTHON:-python3}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp} PYTHONUNBUFFERED=1

if [[ $quick == 1 ]]; then
    suite_s=${SUITE_S:-240}; processes_s=${PROCESSES_S:-300}; bench_s=${BENCH_S:-240}
    repro_s=${REPRO_S:-120}; test_s=${TEST_S:-120}
    tests=(tests/test_api.py tests/gpu/test_device_loss.py tests/test_answers.py)
    bench_args=(--repeat 1)
    repro_args=(--frames 1 --bodies 300 --stairs 60 --deadline 30 --dump-after 100)
else
    suite_s=${SUITE_S:-240}; processes_s=${PROCESSES_S:-300}; bench_s=${BENCH_S:-90}
    repro_s=${REPRO_S:-60}; test_s=${TEST_S:-120}
    tests=(tests)
    bench_args=(--repeat 3)
    repro_args=(--deadline 20 --dump-after 45)  # the stacks before the step's 60 s run out
fi
for budget in "$suite_s" "$processes_s" "$bench_s" "$repro_s" "$test_s"; do
    [[ $budget =~ ^[1-9][0-9]*$ ]] || { echo "gpu-check: budgets are whole seconds, got '$budget'" >&2; exit 2; }
done

summary=$out/summary.txt
: > "$summary"
note() { echo "$*" | tee -a "$summary"; }

# step NAME BUDGET LOG COMMAND...: the command under an outer timeout, its output line-buffered
# into LOG as it comes, its exit status and seconds into the summary.
step() {
    local name=$1 budget=$2 log=$3 t0 rc
    shift 3
    t0=$(date +%s)
    timeout --kill-after=15 "$budget" stdbuf -oL -eL "$@" 2>&1 | stdbuf -oL tee "$log"
    rc=${PIPESTATUS[0]}
    local verdict="exit $rc"
    [[ $rc == 124 || $rc == 137 ]] && verdict="STOPPED at its budget of $budget s (exit $rc)"
    note "$name: $verdict, $(( $(date +%s) - t0 )) s"
    return "$rc"
}

cd "$root"
note "gpu-check: $(date -u '+%Y-%m-%d %H:%M:%S UTC'), $(git rev-parse --short HEAD 2>/dev/null || echo 'no git'), quick=$quick"

if [[ -n $wheels ]]; then
    step install 300 "$out/install.log" "$py" -m pip install --no-index --find-links "$wheels" \
        "pycinder[test]" pytest-timeout \
        || true
    "$py" -c "import pycinder, pytest, pytest_timeout" 2>/dev/null \
        || step install-minimal 300 "$out/install-minimal.log" "$py" -m pip install --no-index \
            --find-links "$wheels" pycinder pytest pytest-timeout hypothesis
fi

step adapter 60 "$out/adapter.txt" "$py" - <<'PYEOF'
import platform, sys
import wgpu
print(f"python {sys.version.split()[0]} on {platform.platform()}, wgpu {wgpu.__version__}")
for adapter in wgpu.gpu.enumerate_adapters_sync():
    info = dict(adapter.info)
    print("adapter:", " | ".join(f"{k}={info.get(k, '')}" for k in
                                 ("device", "vendor", "backend_type", "adapter_type",
                                  "driver", "description")))
import pycinder
from pycinder.gpu.device import get_gpu
gpu = get_gpu()
print(f"pycinder {pycinder.__version__} chose: {gpu.description}; driver "
      f"{gpu.adapter.info.get('description', '')}")
PYEOF
if command -v nvidia-smi > /dev/null; then
    timeout 60 nvidia-smi >> "$out/adapter.txt" 2>&1
else
    echo "nvidia-smi: not present" >> "$out/adapter.txt"
fi

# The suite: -n only where xdist is installed; a test's own timeout on a thread, so that a
# blocked GPU wait is named and dumped, and the outer timeout of the step above it.
parallel=()
"$py" -c "import xdist" 2>/dev/null && parallel=(-n "$(nproc)")
timeouts=()
if "$py" -c "import pytest_timeout" 2>/dev/null; then
    timeouts=(--timeout "$test_s" --timeout-method thread)
else
    note "pytest-timeout is not installed: tests run under the outer timeout alone"
fi
step suite "$suite_s" "$out/suite.log" "$py" -m pytest -v -p no:cacheprovider -p no:randomly \
    -rfEs "${parallel[@]}" "${timeouts[@]}" --ignore=tests/test_processes.py "${tests[@]}"
suite_rc=$?
grep -E "(FAILED|ERROR|Timeout)" "$out/suite.log" | grep -v "^=" | sort -u > "$out/failures.txt"
if [[ $suite_rc == 124 || $suite_rc == 137 ]]; then
    # the test that was running: its line has no verdict yet
    # (under xdist, lines start with "[gwN] ")
    running=$(grep -E '^(\[gw[0-9]+\] )?tests/.*::' "$out/suite.log" \
        | grep -vE ' (PASSED|FAILED|SKIPPED|ERROR|XFAIL|XPASS)' | tail -1)
    note "suite: stopped while running ${running:-(no test named)}"
    echo "STOPPED while running: ${running:-(no test named)}" >> "$out/failures.txt"
fi
note "suite: $(grep -cE ' PASSED' "$out/suite.log") passed, $(grep -cE ' SKIPPED' "$out/suite.log") skipped, $(wc -l < "$out/failures.txt") failure lines (failures.txt)"

step processes "$processes_s" "$out/processes.log" "$py" -m pytest -v -p no:cacheprovider \
    -p no:randomly "${timeouts[@]}" tests/test_processes.py || true

cuda=$(timeout 120 "$py" -c "
import warp as wp
wp.config.quiet = True
wp.init()
print(wp.get_cuda_device_count())" 2>/dev/null | tail -1)
if [[ -z $cuda ]]; then
    note "warp: not installed; the Warp rows are left out (pycinder bench names them)"
elif [[ $cuda == 0 ]]; then
    note "warp on CUDA: SKIPPED (Warp sees no CUDA device: its rows ran on the CPU)"
else
    note "warp on CUDA: $cuda device(s)"
fi
step bench "$bench_s" "$out/bench.log" "$py" -m pycinder bench stairs many deforming \
    --peers warp "${bench_args[@]}" --out "$out/bench" --stem gpu-check --no-progress || true

step repro "$repro_s" "$out/repro.log" "$py" "$root/scripts/repro-warp-hang.py" \
    "${repro_args[@]}" || true

note "gpu-check: done $(date -u '+%H:%M:%S UTC'); answers in $out"
