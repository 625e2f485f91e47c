#!/usr/bin/env bash
# The Python validators of the FMU (fmu/tests): a virtual environment at
# target/py-env with FMPy (validate, simulate) and the FMU Manipulation Toolbox
# (`fmutool -check`), at pinned versions so a validator's update cannot change a result
# unnoticed. Idempotent: an environment that already has both at these versions is
# left as it is. Prints the environment's path (the tests find it there, or at
# $SIMROD_PY_ENV).
set -euo pipefail
cd "$(dirname "$0")/.."

FMPY=0.3.32
FMUTOOL=2.0
env_dir="${SIMROD_PY_ENV:-$PWD/target/py-env}"
stamp="$env_dir/.simrod-pins"
want="fmpy==$FMPY fmu-manipulation-toolbox==$FMUTOOL"

if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  python3 -m venv "$env_dir" >&2
  "$env_dir/bin/python" -m pip install --quiet --disable-pip-version-check $want >&2
  echo "$want" >"$stamp"
fi
echo "$env_dir"
