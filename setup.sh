#!/usr/bin/env bash
# Sets pgi up on a fresh Debian 12 machine, then runs the main job (the default
# study). Safe to run again: it installs only what is missing and rebuilds
# only what changed.
#   ./setup.sh            set up, then run the default workflow
#   ./setup.sh --no-run   set up only
set -euo pipefail
cd "$(dirname "$0")"

run_main_job=1
[ "${1:-}" = "--no-run" ] && run_main_job=0

# System packages: Python with venv and headers, OpenVDB's Python module,
# LLVM >= 16 for Mitsuba's fast variant, Chromium for the report tests.
apt_packages=(python3-venv python3-dev python3-openvdb libllvm19 g++ chromium)
missing=()
for p in "${apt_packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo=sudo
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q "${missing[@]}"
fi

# A venv on the system Python that also sees Debian's OpenVDB module; it needs numpy < 2.
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q "nanobind>=2.4" "scikit-build-core>=0.10"
echo "setup: building and installing pgi (C++ core and Python packages)"
.venv/bin/python -m pip install -q --no-build-isolation -e ".[dev]"
.venv/bin/python -c "import renderer._core, pyopenvdb, mitsuba, embreex, OpenImageIO" \
  || { echo "setup: an installed module does not import" >&2; exit 1; }
echo "setup: done"

if [ "$run_main_job" -eq 1 ]; then
  .venv/bin/snakemake --cores 2 --configfile configs/default.yaml
  echo "report: $(pwd)/reports/index.html"
fi
