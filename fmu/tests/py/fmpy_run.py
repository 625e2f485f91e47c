"""Simulate an FMU headless with FMPy on an input table; write every output exactly.

usage: fmpy_run.py FMU INPUT.csv STOP_TIME OUTPUT_INTERVAL OUT_PREFIX

INPUT.csv: a header `time,<input name>,...`, then rows of numbers (written with enough
digits to read back exactly). FMPy applies the table at each communication point (its
linear interpolation is exact where the point is a row's time). Writes
OUT_PREFIX.names (the result's columns, one a line: `time` then every output) and
OUT_PREFIX.f64 (the result, row by row, little-endian float64), so nothing is rounded
on the way back to the test.
"""

import sys

import numpy as np
from fmpy import read_model_description, simulate_fmu


def main():
    fmu, table, stop, interval, prefix = sys.argv[1:6]
    inputs = np.genfromtxt(table, delimiter=",", names=True, dtype=np.float64)
    md = read_model_description(fmu)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    result = simulate_fmu(
        fmu,
        start_time=0.0,
        stop_time=float(stop),
        output_interval=float(interval),
        input=inputs,
        output=outputs,
        validate=True,
    )
    names = list(result.dtype.names)
    with open(prefix + ".names", "w", encoding="utf-8") as f:
        f.write("\n".join(names) + "\n")
    columns = [np.asarray(result[n], dtype="<f8") for n in names]
    np.column_stack(columns).astype("<f8").tofile(prefix + ".f64")
    print(f"fmpy: {len(result)} rows x {len(names)} columns")


if __name__ == "__main__":
    main()
