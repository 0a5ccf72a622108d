#!/bin/sh
# Builds the peers the benchmarks compare mavscope with into their own venv (benchmarks/out/peers),
# apart from the project's: fasttlogparser (C++, pybind11; built from its sdist as its README says,
# without build isolation) and numpy, which it imports.
#     scripts/peer-venv.sh [PYTHON]      (default python3.11)
set -eu
cd "$(dirname "$0")/.."
PY="${1:-python3.11}"
VENV=benchmarks/out/peers
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet scikit-build-core pybind11 numpy
"$VENV/bin/python" -m pip install --quiet --no-build-isolation fasttlogparser
"$VENV/bin/python" -c "import fasttlogparser, importlib.metadata as m; print('fasttlogparser', m.version('fasttlogparser'), 'in $VENV')"
