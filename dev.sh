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

build_interfaces() {
  # The interface packages the node uses that are not among the PyPI ROS wheels
  # (simulation_interfaces, tf2_msgs), generated from interfaces/ with the rosidl wheels into
  # the environment itself (its lib/ is on the wheels' library path); rebuilt only when their
  # definitions or the pinned versions change (build folders kept: a rebuild is incremental)
  local stamp pkg build log
  stamp="$VENV/.interfaces-$( (cat requirements.txt; find interfaces -type f | LC_ALL=C sort \
    | xargs cat) | sha1sum | cut -c1-12)"
  [ -f "$stamp" ] && return 0
  if ! command -v cmake > /dev/null || ! command -v c++ > /dev/null; then
    echo "not building simulation_interfaces and tf2_msgs: cmake and a C++ compiler are" \
         "needed; sim_node runs without the simulation_interfaces services and /tf" >&2
    return 0
  fi
  echo "building simulation_interfaces and tf2_msgs into $VENV (first run only, about a minute)" >&2
  for pkg in tf2_msgs simulation_interfaces; do
    build="$VENV/build/interfaces/$pkg"
    log="$build/build.log"
    mkdir -p "$build"
    if ! ( export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 AMENT_PREFIX_PATH="$PWD/$VENV" \
             CMAKE_PREFIX_PATH="$PWD/$VENV" PATH="$PWD/$VENV/bin:$PATH" \
             LD_LIBRARY_PATH="$PWD/$VENV/lib:$(ls -d "$PWD/$VENV"/lib/python3*/site-packages/ros_*.libs | paste -sd:)"
           cmake -S "interfaces/$pkg" -B "$build" -DBUILD_TESTING=OFF \
             -DCMAKE_INSTALL_PREFIX="$PWD/$VENV" -DPython3_EXECUTABLE="$PWD/$VENV/bin/python" \
             -DCMAKE_PROJECT_INCLUDE="$PWD/interfaces/wheel_paths.cmake" \
           && cmake --build "$build" -j "$(nproc)" && cmake --install "$build" ) > "$log" 2>&1; then
      echo "building $pkg failed; the last lines of $log:" >&2
      tail -15 "$log" >&2
      exit 1
    fi
  done
  rm -f "$VENV"/.interfaces-*
  touch "$stamp"
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
  build_interfaces
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
