#!/usr/bin/env bash
# The Python tools the tests use as independent readers, in a local virtual environment
# (third_party/venv, git-ignored): the `mcap` package from PyPI reads the bench's MCAP files,
# and `rerun-sdk` (the version matching the rerun crate) verifies its .rrd files
# (`rerun rrd verify`); its `rerun` binary is also the viewer `run --rerun` spawns; and
# `junitparser` reads the JUnit reports of `stairbench regress`.
# Idempotent: a no-op when they are installed. Called by the Makefile.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=third_party/venv
MCAP_VERSION=1.6.0
RERUN_VERSION=0.36.3
JUNITPARSER_VERSION=5.0.3

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import mcap, junitparser" 2>/dev/null \
  && [ "$("$VENV/bin/python" -c 'import rerun; print(rerun.__version__)' 2>/dev/null)" = "$RERUN_VERSION" ]; then
  exit 0
fi
if ! python3 -m venv --help >/dev/null 2>&1; then
  echo "error: python3's venv module is missing (Debian: apt-get install python3-venv)" >&2
  exit 1
fi
echo "setup: $VENV with mcap==$MCAP_VERSION, rerun-sdk==$RERUN_VERSION and junitparser==$JUNITPARSER_VERSION from PyPI (the tests' independent readers)"
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "mcap==$MCAP_VERSION" "rerun-sdk==$RERUN_VERSION" "junitparser==$JUNITPARSER_VERSION"
