#!/usr/bin/env bash
# One entry point for users and CI. Creates .venv (numpy, scipy, numba, ROS 2 Jazzy wheels, ...)
# on first use, then:
#   ./dev.sh demo          the whole product on the default scenario (paper scenario 6): sim_node
#                          brakes by itself, records the run to runs/, stops once the train has
#                          stopped; then the report and its plots
#   ./dev.sh test [ARGS]   the whole test suite (ARGS go to pytest)
#   ./dev.sh bench         the speed benchmark
#   ./dev.sh docs [ARGS]   build the documentation site into site/ (warnings are errors;
#                          ARGS go to mkdocs build, e.g. --site-dir DIR)
#   ./dev.sh run CMD ...   any command inside the environment (e.g. ./dev.sh run ltd-brake validate)
set -euo pipefail
cd "$(dirname "$0")"
VENV=${LTD_VENV:-.venv}
PY=${PYTHON:-python3}

pip_install() {
  # quiet, and without this machine's notes about absent local package mirrors
  "$VENV/bin/python" -m pip install --quiet "$@" 2> >(grep -v 'is ignored: it is neither' >&2)
}

setup() {
  if [ ! -x "$VENV/bin/python" ]; then
    echo "creating virtual environment $VENV" >&2
    "$PY" -m venv "$VENV"
  fi
  local stamp
  stamp="$VENV/.installed-$(cat requirements.txt setup.py | sha1sum | cut -c1-12)"
  if [ ! -f "$stamp" ]; then
    echo "installing dependencies into $VENV (first run only)" >&2
    pip_install --upgrade pip
    pip_install -r requirements.txt
    pip_install --no-deps -e .
    rm -f "$VENV"/.installed-*
    touch "$stamp"
  fi
  export PATH="$PWD/$VENV/bin:$PATH"
  # DDS discovery stays on this machine unless the caller says otherwise
  export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
}

cmd=${1:-demo}
shift || true
case "$cmd" in
  demo)
    setup
    run_dir="runs/demo_$(date +%Y%m%d-%H%M%S)"
    rtf="${RTF:-0.0}"
    [[ "$rtf" == *.* ]] || rtf="$rtf.0"  # a ROS double parameter needs the decimal point
    sim_node --ros-args -p auto_brake_at_s:=1.0 -p real_time_factor:="$rtf" \
      -p record:=true -p record_dir:="$run_dir" -p shutdown_after_stop_s:=2.0 "$@"
    echo
    exec ltd-brake report "$run_dir" ;;
  test)  setup; exec python -m pytest "$@" ;;
  bench) setup; exec python benchmarks/bench_integrator.py "$@" ;;
  docs)  setup; NO_MKDOCS_2_WARNING=1 exec python -m mkdocs build --strict "$@" ;;
  run)   setup; exec "$@" ;;
  setup) setup ;;
  *) echo "usage: ./dev.sh demo|test|bench|docs|run CMD...|setup" >&2; exit 2 ;;
esac
