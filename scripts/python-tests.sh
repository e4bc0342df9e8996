#!/usr/bin/env bash
# Builds the sph_splat Python package (python/, PyO3 + maturin) into a
# fresh virtual environment and runs its pytest suite. Needs python3 with
# venv (Debian: python3-venv) and the network for pip.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${SPH_PY_VENV:-$(mktemp -d)/venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q "maturin>=1.7,<2" "numpy>=1.21" "pytest>=7"
(cd python && VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH" maturin develop --release -q)
"$venv/bin/python" -m pytest -q python/tests
