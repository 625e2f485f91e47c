#!/usr/bin/env python3
"""Write the MAT-file fixtures of workbench/io/tests/mat_scipy.rs.

The fixtures prove the MAT reader (workbench/io/src/measure/mat.rs) against files it did
not write itself: all but two are written by scipy.io.savemat. The two `stored_small_*`
files imitate MATLAB's own `save`, which stores a double array of small integers in a
smaller storage type (miINT16, miUINT8, ...); scipy cannot write that, so they are built
here byte by byte from the MAT-file format spec, and scipy.io.loadmat reads them back
before they are kept (so they are checked by scipy, not by our reader).

Known values (k = 0, 1, ..., N-1 with N = 100), which the Rust test recomputes:
    time         = 0.001 * k                  (double, [s])
    C_Kistler_L  = k - 50 (signed/float classes) or k (unsigned classes)
    C_Kistler_L_unit = 'N m'

Files (in workbench/io/tests/fixtures/mat/):
    class_<cls>.mat, class_<cls>_z.mat   one per numeric class (double, single, int8..int64,
                                         uint8..uint64), C_Kistler_L in that class; `_z`
                                         compressed and with row vectors. class_double.mat
                                         also holds metadata the reader ignores (a scalar,
                                         a complex scalar, a text).
    logical.mat                          brake_on = (k % 3 == 0), a logical vector
    char_channel.mat                     C_Kistler_L = 'abc'
    matrix_channel.mat                   C_Kistler_L is 100x2
    complex_channel.mat                  C_Kistler_L = (k - 50) + 1j k
    cell_var.mat, struct_var.mat,
    sparse_var.mat                       a cell `notes`, a struct `meta`, a sparse `stiff`
                                         next to a good channel
    short_channel.mat                    C_Kistler_L has N-1 samples
    nan_channel.mat                      I_XLML_2_2 (unit A) is NaN at k = 7
    stored_small_le.mat, stored_small_be.mat
                                         MATLAB-style storage, little and big endian (see
                                         `stored_small`)

Generated with Python 3.11.7, scipy 1.17.1, numpy 2.4.6. Regenerating changes the date in
scipy's header text (and the compressed bytes if zlib differs), nothing else.

Usage:
    python3 -m venv /tmp/venv-mat && /tmp/venv-mat/bin/pip install scipy numpy
    /tmp/venv-mat/bin/python scripts/make-mat-fixtures.py
"""

import os
import struct
import zlib

import numpy as np
import scipy.io
import scipy.sparse

N = 100
K = np.arange(N)
TIME = 0.001 * K
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "workbench", "io", "tests",
                   "fixtures", "mat")
CLASSES = ["double", "single", "int8", "int16", "int32", "int64",
           "uint8", "uint16", "uint32", "uint64"]
DTYPES = {"double": np.float64, "single": np.float32}


def channel(cls):
    """The known C_Kistler_L values in class `cls`."""
    dtype = DTYPES.get(cls, np.dtype(cls))
    values = K if cls.startswith("uint") else K - 50
    return values.astype(dtype)


def save(name, variables, **kw):
    path = os.path.join(OUT, name)
    scipy.io.savemat(path, variables, **kw)
    print(f"{name}: {os.path.getsize(path)} bytes")


def good(**extra):
    """time and a good C_Kistler_L with its unit, then `extra`."""
    return {"time": TIME, "C_Kistler_L": channel("double"), "C_Kistler_L_unit": "N m", **extra}


def class_files():
    for cls in CLASSES:
        v = {"time": TIME, "C_Kistler_L": channel(cls), "C_Kistler_L_unit": "N m"}
        if cls == "double":
            v.update(fs=1000.0, z0=1 + 2j, comment="bench run 12, ignored")
        save(f"class_{cls}.mat", v, oned_as="column")
        save(f"class_{cls}_z.mat", v, oned_as="row", do_compression=True)


def error_files():
    save("logical.mat", {"time": TIME, "brake_on": K % 3 == 0})
    save("char_channel.mat", {"time": TIME, "C_Kistler_L": "abc", "C_Kistler_L_unit": "N m"})
    save("matrix_channel.mat", {"time": TIME, "C_Kistler_L": np.zeros((N, 2)), "C_Kistler_L_unit": "N m"})
    save("complex_channel.mat",
         {"time": TIME, "C_Kistler_L": (K - 50) + 1j * K, "C_Kistler_L_unit": "N m"})
    notes = np.empty((1, 2), dtype=object)
    notes[0, 0], notes[0, 1] = "a note", 1.0
    save("cell_var.mat", good(notes=notes))
    save("struct_var.mat", good(meta={"operator": "kb", "fs": 1000.0}))
    save("sparse_var.mat", good(stiff=scipy.sparse.csc_matrix(np.eye(3))))
    save("short_channel.mat", {"time": TIME, "C_Kistler_L": channel("double")[:-1],
                               "C_Kistler_L_unit": "N m"})
    current = (K - 50).astype(np.float64)
    current[7] = np.nan
    save("nan_channel.mat", {"time": TIME, "I_XLML_2_2": current, "I_XLML_2_2_unit": "A"})


# ---- MATLAB-style storage, built from the MAT-file format spec (Level 5)

MI = {"int8": 1, "uint8": 2, "int16": 3, "uint16": 4, "int32": 5, "uint32": 6, "double": 9}
MX = {"char": 4, "double": 6, "single": 7, "int32": 12}


def element(e, mi, data):
    """A data element: the small format for up to 4 bytes (as MATLAB writes names such
    as `time`), else tag + data + padding to 8 bytes."""
    if 0 < len(data) <= 4:
        return struct.pack(e + "I", len(data) << 16 | mi) + data.ljust(4, b"\0")
    return struct.pack(e + "II", mi, len(data)) + data + b"\0" * (-len(data) % 8)


def matrix(e, name, mx, dims, mi, data):
    body = (element(e, MI["uint32"], struct.pack(e + "II", mx, 0))
            + element(e, MI["int32"], struct.pack(e + "ii", *dims))
            + element(e, MI["int8"], name.encode())
            + element(e, mi, data))
    return struct.pack(e + "II", 14, len(body)) + body


def numeric(e, name, mx, storage, values):
    data = np.asarray(values, dtype=np.dtype(storage).newbyteorder(e)).tobytes()
    return matrix(e, name, MX[mx], (len(values), 1), MI[storage], data)


def text(e, name, s):
    """A char row vector stored as UTF-16 (miUINT16), as MATLAB does."""
    data = s.encode("utf-16-be" if e == ">" else "utf-16-le")
    return matrix(e, name, MX["char"], (1, len(s)), MI["uint16"], data)


def compressed(e, elem):
    z = zlib.compress(elem)
    return struct.pack(e + "II", 15, len(z)) + z


# name -> (class, storage type, values) of stored_small_*.mat
STORED = {
    "C_Kistler_L": ("double", "int16", K - 50),
    "count_u8": ("double", "uint8", K),
    "count_u16": ("double", "uint16", K * 500),
    "big_i32": ("double", "int32", (K - 50) * 100000),
    "single_i16": ("single", "int16", K - 50),
    "int32_i16": ("int32", "int16", K - 50),
}


def stored_small(e, name):
    head = b"MATLAB 5.0 MAT-file, Platform: simrod fixture (MATLAB-style storage)".ljust(116)
    head += b"\0" * 8 + struct.pack(e + "H", 0x0100) + (b"IM" if e == "<" else b"MI")
    body = numeric(e, "time", "double", "double", TIME)
    for var, (mx, storage, values) in STORED.items():
        body += numeric(e, var, mx, storage, values)
    body += compressed(e, text(e, "C_Kistler_L_unit", "N m"))
    path = os.path.join(OUT, name)
    with open(path, "wb") as f:
        f.write(head + body)
    check_stored(path)
    print(f"{name}: {os.path.getsize(path)} bytes (checked by scipy.io.loadmat)")


def check_stored(path):
    """scipy must read the hand-built file to the intended classes and values."""
    m = scipy.io.loadmat(path, mat_dtype=True)
    assert np.array_equal(m["time"].ravel(), TIME)
    assert m["C_Kistler_L_unit"][0] == "N m"
    for var, (mx, _, values) in STORED.items():
        got = m[var]
        want = np.dtype(DTYPES.get(mx, mx))
        assert got.dtype.newbyteorder("=") == want, (var, got.dtype, want)
        assert got.shape == (N, 1) and np.array_equal(got.ravel(), values), var


def main():
    os.makedirs(OUT, exist_ok=True)
    class_files()
    error_files()
    stored_small("<", "stored_small_le.mat")
    stored_small(">", "stored_small_be.mat")


if __name__ == "__main__":
    main()
