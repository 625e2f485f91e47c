#!/usr/bin/env python3
"""Regenerate the committed seed corpus fuzz/corpus/<target>/ (docs/FUZZING.md).

    python3 fuzz/make_corpus.py BENCH.csv BENCH.mat [SHORT.csv]

BENCH.csv: `simrod bench --profile TP07 --seed 1 --out BENCH.csv` (only a few rows are
kept); BENCH.mat: a short run as MAT (`simrod bench --profile-file short.toml --out
BENCH.mat`, a profile of ~30 ms); SHORT.csv: the same short run as CSV, `--noise none`.
The MAT variants other than simrod's own need scipy (a venv is enough); without it
they are skipped. The toml and serial seeds need nothing but the repository.
"""
import io
import os
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORPUS = os.path.join(ROOT, "fuzz", "corpus")


def put(target, name, data):
    d = os.path.join(CORPUS, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# ---------------------------------------------------------------- csv
def csv_seeds(bench_csv, short_csv):
    lines = open(bench_csv, encoding="utf-8").read().split("\n")
    header, rows = lines[0], [l for l in lines[1:] if l]
    head = rows[:20]
    mid = rows[19999:20019]  # t = 20 s: throttle 50 %, loads on
    put("csv", "bench_head.csv", "\n".join([header] + head) + "\n")
    put("csv", "bench_mid.csv", "\n".join([header] + mid) + "\n")
    if short_csv:
        put("csv", "bench_short_noise_none.csv", open(short_csv, "rb").read())

    def cells(r):
        return r.split(",")

    hcells = cells(header)
    mid_rows = [cells(r) for r in mid[:12]]
    # Semicolon separator and decimal comma (European DAQ export).
    put("csv", "semicolon_decimal_comma.csv",
        ";".join(hcells) + "\n" + "".join(";".join(c.replace(".", ",") for c in r) + "\n" for r in mid_rows))
    # Tab separator, decimal comma.
    put("csv", "tab_decimal_comma.tsv",
        "\t".join(hcells) + "\n" + "".join("\t".join(c.replace(".", ",") for c in r) + "\n" for r in mid_rows))
    # Units in a second header row, names alone in the first.
    names = [h.split(" [")[0] for h in hcells]
    units = ["[" + h.split(" [")[1] if " [" in h else "" for h in hcells]
    put("csv", "unit_row.csv", ",".join(names) + "\n" + ",".join(units) + "\n"
        + "".join(",".join(r) + "\n" for r in mid_rows))
    # Units in parentheses, comments and blank lines before and inside, CRLF.
    paren = [h.replace(" [", " (").replace("]", ")") for h in hcells]
    put("csv", "comments_crlf_paren.csv",
        "# exported by the bench PC\r\n\r\n# run 17\r\n" + ",".join(paren) + "\r\n"
        + "".join(",".join(r) + "\r\n" + ("# marker\r\n" if i == 4 else "") for i, r in enumerate(mid_rows)))
    # BOM, time in ms, quoted header fields, trailing separators.
    q = ['"' + h + '"' for h in ["time [ms]"] + hcells[1:]]
    put("csv", "bom_ms_quoted_trailing.csv", "\ufeff" + ",".join(q) + ",\n"
        + "".join(",".join([str(round(float(r[0]) * 1000, 3))] + r[1:]) + ",\n" for r in mid_rows))
    # Latin-1 (not UTF-8): time in µs, a temperature channel T [°C].
    lat = "zeit [\u00b5s];T [\u00b0C];C_Kistler_L [N\u00b7m]\n" + "".join(
        f"{i * 1000};{20 + i * 0.1:.1f};{0.5 * i:.2f}\n".replace(".", ",") for i in range(15))
    put("csv", "latin1_us_degC.csv", lat.encode("latin-1", errors="replace"))
    # Irregular sampling (resampled onto the median interval), unknown channels.
    ts = [0.0, 0.001, 0.002, 0.0031, 0.004, 0.0049, 0.006, 0.007, 0.0082, 0.009, 0.010]
    put("csv", "irregular_resample.csv", "t,speed [rpm],raw\n" + "".join(
        f"{t},{1000 * t:.4f},{i % 3}\n" for i, t in enumerate(ts)))
    # Small shapes.
    put("csv", "minimal.csv", "t,x\n0,1\n1,2\n")
    put("csv", "one_row.csv", "Time [s];a\n0,5;1\n")
    put("csv", "quoted_sep.csv", 'time;"a;b [V]";c\n0;"1,5";2\n0,5;"2,5";3\n1;"3,5";4\n')
    put("csv", "exponent_numbers.csv", "time [s],I_DC [mA],V_DC [kV]\n1e-3,1.5E3,2.4e-2\n2e-3,-1.5e+3,2.4E-2\n3e-3,0,0.024\n")
    # Refused files (the error paths): gap, duplicate and backwards time, NaN,
    # truncated row, extra field, non-numeric, mixed `.`/`,`, two time columns, no time.
    put("csv", "err_gap.csv", "t,x\n0,0\n1,1\n2,2\n3,3\n20,4\n21,5\n")
    put("csv", "err_time_back.csv", "t,x\n0,0\n1,1\n1,2\n0.5,3\n")
    put("csv", "err_nan_inf.csv", "t,x,y\n0,NaN,1\n1,inf,-inf\n")
    put("csv", "err_truncated_extra.csv", "t,x,y\n0,1,2\n1,2\n2,3,4,5\n")
    put("csv", "err_text_mixed_sep.csv", "t;x\n0;1.000,5\n1;abc\n")
    put("csv", "err_two_time_no_unit.csv", "t,time,C_Kistler_L\n0,0,1\n1,1,2\n")
    put("csv", "err_bad_units.csv", "time [h],C_Kistler_L [V],T [\u00b0C]\n0,1,2\n1,2,3\n")
    put("csv", "err_duplicate.csv", "t,a,a,t\n0,1,2,3\n")


# ---------------------------------------------------------------- mat
def mat_seeds(bench_mat):
    put("mat", "simrod_bench.mat", open(bench_mat, "rb").read())
    try:
        import numpy as np
        import scipy.io as sio
    except ImportError:
        print("scipy not found: only simrod's own MAT file written", file=sys.stderr)
        return
    t = np.arange(1, 13) * 1e-3
    base = {
        "time": t,
        "C_Kistler_L": np.sin(t * 300) * 20,
        "C_Kistler_L_unit": "N m",
        "SuT_Throttle": np.linspace(0, 60, t.size),
        "SuT_Throttle_unit": "%",
        "I_XLML_2_2": np.cos(t * 100),
        "I_XLML_2_2_unit": "A",
    }

    def save(name, d, **kw):
        b = io.BytesIO()
        sio.savemat(b, d, **kw)
        put("mat", name, b.getvalue())

    save("v5_double.mat", base)
    save("v5_compressed.mat", base, do_compression=True)
    save("v5_row_vectors.mat", base, oned_as="row")
    save("v5_classes.mat", {
        "t": (t * 1000).astype(np.uint16), "t_unit": "ms",
        "a": np.arange(12, dtype=np.int8), "b": np.arange(12, dtype=np.int32) * -5,
        "c": np.arange(12, dtype=np.float32) / 3, "d": np.arange(12, dtype=np.uint64),
        "e": np.arange(12, dtype=np.int64), "f": np.arange(12, dtype=np.uint8),
        "g": np.arange(12, dtype=np.int16), "h": np.arange(12, dtype=np.uint32)})
    save("v5_metadata_scalars.mat", dict(base, fs=1000.0, run=np.int32(17), note="bench PC 2"),
         do_compression=True)
    save("v5_units_all.mat", {"time": t, "time_unit": "s", "I_DC": t * 2, "I_DC_unit": "mA",
                              "V_DC": t + 24, "V_DC_unit": "V", "x9": t, "x9_unit": "\u00b0C"})
    # Refused: a matrix, complex data, a wrong length, a struct and a cell, no time.
    save("err_matrix_complex.mat", {"time": t, "m": np.ones((3, 4)), "z": t + 1j * t})
    save("err_wrong_length.mat", {"time": t, "x": t[:5]})
    save("err_struct_cell.mat", {"time": t, "s": {"a": 1.0, "b": t},
                                 "c": np.array([t, "x"], dtype=object)})
    save("err_no_time.mat", {"x": t, "y": t}, do_compression=True)
    save("err_sparse_logical.mat", {"time": t, "sp": __import__("scipy.sparse").sparse.eye(4).tocsc(),
                                    "l": t > 0.005})
    b = io.BytesIO()
    sio.savemat(b, {"time": t, "x": t}, format="4")
    put("mat", "v4.mat", b.getvalue())
    # A v7.3 (HDF5) header: refused with a hint.
    hdr = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    hdr = hdr.ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0200) + b"IM"
    put("mat", "v73_header.mat", hdr + b"\x89HDF\r\n\x1a\n" + b"\0" * 64)
    # Big endian ("MI"): an uncompressed file with every element swapped.
    b = io.BytesIO()
    sio.savemat(b, {"time": t, "V_DC": t + 24, "V_DC_unit": "V", "n": np.arange(12, dtype=np.int16)})
    put("mat", "v5_big_endian.mat", to_big_endian(b.getvalue()))


WIDTH = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8, 16: 1, 17: 2, 18: 4}


def to_big_endian(le):
    """A little-endian, uncompressed MAT v5 file in big-endian byte order."""
    out = bytearray(le[:124]) + b"\x01\x00MI"
    p = 128
    while p < len(le):
        ty, size = struct.unpack_from("<II", le, p)
        assert ty == 14, "uncompressed miMATRIX only"
        body, q, sub = le[p + 8:p + 8 + size], 0, bytearray()
        while q < len(body):
            first = struct.unpack_from("<I", body, q)[0]
            if first >> 16:  # small element: type and size in one word, data in 4 bytes
                sty, n, start, step = first & 0xFFFF, first >> 16, q + 4, 8
                head = struct.pack(">I", first)
            else:
                sty, n = first, struct.unpack_from("<I", body, q + 4)[0]
                start, step = q + 8, 8 + (n + 7) // 8 * 8
                head = struct.pack(">II", sty, n)
            w = WIDTH[sty]
            data = bytearray(body[start:start + step - (start - q)])
            for i in range(0, n - n % w, w):
                data[i:i + w] = data[i:i + w][::-1]
            sub += head + data
            q += step
        out += struct.pack(">II", ty, len(sub)) + sub
        p += 8 + (size + 7) // 8 * 8
    return bytes(out)


# ---------------------------------------------------------------- toml_files
TOML_SEL = {  # selector byte -> the parser (fuzz_targets/toml_files.rs, PARSERS)
    0: ["workbench/examples/profile.toml"],
    1: ["workbench/examples/effects.toml"],
    2: ["workbench/examples/mapping.toml"],
    3: ["model-core/data/parameters.toml"],
    4: ["model-core/data/throttle_input_map.csv", "model-core/data/speed_map_fwd.csv",
        "model-core/data/speed_map_rev.csv", "model-core/data/axle_friction_L.csv"],
    5: ["model-core/data/load_torque_L.csv", "model-core/data/load_current_R.csv",
        "model-core/data/load_power_L.csv", "model-core/data/sut_inverter_power.csv"],
    6: ["model-core/data/profiles/TP07.csv", "model-core/data/profiles/TP12.csv",
        "model-core/data/profiles/TP14.csv"],
    7: ["workbench/examples/noise.toml"],
    8: ["workbench/examples/bench_effects.toml", "workbench/examples/effects.toml"],
}

# Files with everything switched on (the examples keep most of it commented out).
TOML_EXTRA = {
    0: {"profile_minimal.toml": '[[set]]\nduration_s = 1\n',
        "profile_scales.toml": 'name = "x"\nthrottle_scale = -1.5\nload_scale = 0.5\n'
                               '[[set]]\nduration_s = 0.5\nthrottle_pct = -100\nload_l_pct = 100\n'
                               'load_r_pct = -20.5\nthrottle = "interpolate"\nload = "interp"\n'},
    1: {"effects_uncommented.toml": None},  # filled from effects.toml below
    2: {"mapping_full.toml": '[rename]\n"Torque L" = "C_Kistler_L"\nzeit = "time"\n'
                             '[scale]\n"Torque L" = -1\nI = 1e-3\n[unit]\n"Torque L" = "N m"\nzeit = "ms"\n'},
    7: {"noise_partial.toml": 'torque = { sigma = 0.1, at_limit = 1 }\n[encoders]\nkistler_ppr = 60\n'},
    8: {"bench_effects_uncommented.toml": None},
}


def uncomment(text):
    """Switch on commented-out `#[section]` and `#key = value` lines of an example."""
    out = []
    for line in text.splitlines():
        s = line.lstrip()
        if s.startswith("#[") or (s.startswith("#") and "=" in s and not s.startswith("# ")):
            out.append(s[1:])
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def toml_seeds():
    for sel, files in TOML_SEL.items():
        for f in files:
            put("toml_files", f"{sel}_{os.path.basename(f)}", bytes([sel]) + open(os.path.join(ROOT, f), "rb").read())
    for sel, extra in TOML_EXTRA.items():
        for name, text in extra.items():
            if text is None:
                src = "workbench/examples/effects.toml" if sel == 1 else "workbench/examples/bench_effects.toml"
                text = uncomment(open(os.path.join(ROOT, src), encoding="utf-8").read())
            put("toml_files", f"{sel}_{name}", bytes([sel]) + text.encode())


# ---------------------------------------------------------------- serial
def fletcher16(b):
    a = s = 0
    for x in b:
        a = (a + x) % 255
        s = (s + a) % 255
    return (s << 8) | a


def frame(kind, payload):
    body = bytes([kind, len(payload)]) + payload
    return b"\xa5\x5a" + body + struct.pack("<H", fletcher16(body))


def inputs(th, ll, lr, v):
    return frame(ord("I"), struct.pack("<4f", th, ll, lr, v))


def serial_seeds():
    end = frame(ord("E"), b"")
    out_payload = struct.pack("<IQ", 7, 7000) + struct.pack("<18f", *[i * 0.5 for i in range(18)])
    stats = struct.pack("<12I", *range(1000, 1012))
    run = b"".join(inputs(i * 5.0, 10.0, -10.0, 24.0) for i in range(6)) + end
    bad_ck = bytearray(inputs(50, 0, 0, 24))
    bad_ck[-1] ^= 0xFF
    # Mode byte 0: a raw stream through Decoder and frames().
    raw = {
        "raw_inputs_end.bin": run,
        "raw_xil_session.bin": run[:44] + frame(ord("O"), out_payload) + run[44:] + frame(ord("S"), stats),
        "raw_garbage_resync.bin": b"\x00\xa5\xa5\x5a\x49" + b"\xff" * 5 + inputs(1, 2, 3, 24) + b"\xa5" + end,
        "raw_bad_checksum.bin": bytes(bad_ck) + inputs(50, 0, 0, 24),
        "raw_bad_len_kind.bin": frame(ord("I"), b"\0" * 8) + frame(ord("X"), b"") + frame(ord("E"), b"\1") + end,
        "raw_truncated.bin": run[:30],
        "raw_nan_inf.bin": inputs(float("nan"), float("inf"), -0.0, 1e-45),
        "raw_outputs_only.bin": frame(ord("O"), out_payload) + frame(ord("O"), struct.pack("<IQ", 1, 2)),
        "raw_max_payload.bin": frame(0x42, bytes(range(255))),
    }
    for name, data in raw.items():
        put("serial", name, b"\x00" + data)
    # Mode byte 1: a frame-sequence description (fuzz_targets/serial.rs, `build`):
    # control byte (bit 0 clear: bit 1 picks E, else I with 16 payload bytes; bit 0 set:
    # kind and length bytes follow), then the payload.
    seq1 = b"\x00" + struct.pack("<4f", 30, 5, 5, 24) + b"\x00" + bytes(range(16)) + b"\x02"
    seq2 = b"\x01O\x0c" + bytes(12) + b"\x01S\x30" + bytes(range(48)) + b"\x02" + b"\x01\xa5\x02\xa5\x5a"
    put("serial", "seq_accepted.bin", b"\x01" + seq1)
    put("serial", "seq_mixed.bin", b"\x01" + seq2)


# ---------------------------------------------------------------- dictionaries
# libFuzzer's -dict (scripts/fuzz.sh passes fuzz/dict/<target>.dict when present).
# Without a sanitizer, string comparisons (memcmp/bcmp) are not traced, so the words the
# parsers compare against (units, channel and key names) come from here.
CHANNELS = ["time", "Throttle", "SuTMotorEnc", "C_Kistler_L", "C_Kistler_R", "T_Kistler_L", "T_Kistler_R",
            "SiemensEnc", "I_XLML 2.2", "I_XLML BU1", "I_XLMR 2.3", "I_DPU 2.7", "V_DC_busbars", "I_DC", "V_DC",
            "SuT Throttle", "Dm Left", "Dm Right", "gap", "inc:Kistler", "tedge:SiemensEnc"]
UNITS = ["s", "sec", "ms", "us", "\u00b5s", "rpm", "RPM", "1/min", "min^-1", "U/min", "rad/s", "rev/s", "rps",
         "N m", "Nm", "N.m", "N*m", "N\u00b7m", "kN m", "kNm", "mN m", "mNm", "A", "mA", "kA", "V", "mV", "kV",
         "W", "kW", "mW", "%", "\u00b0C", "-"]


def dict_line(word):
    b = word.encode() if isinstance(word, str) else word
    esc = "".join(chr(c) if 32 <= c < 127 and c not in (34, 92) else f"\\x{c:02x}" for c in b)
    return f'"{esc}"\n'


def write_dict(target, words):
    os.makedirs(os.path.join(ROOT, "fuzz", "dict"), exist_ok=True)
    seen, out = set(), [f"# {target}: generated by fuzz/make_corpus.py\n"]
    for w in words:
        if w and w not in seen:
            seen.add(w)
            out.append(dict_line(w))
    with open(os.path.join(ROOT, "fuzz", "dict", f"{target}.dict"), "w") as f:
        f.writelines(out)


def dicts():
    import re
    csv_words = ["t", "zeit", "Time", "TIME", "\ufeff", "\r\n", "\n#", ";", "\t", ",", "\"", "NaN", "inf", "-inf",
                 "e-3", "E+3", "1,5", "0.001"]
    for c in CHANNELS:
        csv_words += [c, c + " ["]
    for u in UNITS:
        csv_words += [u, "[" + u + "]", "(" + u + ")"]
    csv_words += [b"\xb5s", b"[\xb5s]", b"\xb0C", b"[\xb0C]"]  # Latin-1 exports
    write_dict("csv", csv_words)
    mat_words = [b"MATLAB 5.0 MAT-file", b"IM", b"MI", b"\x00\x01IM", b"\x01\x00MI", b"\x00\x02IM",
                 b"\x0e\x00\x00\x00", b"\x0f\x00\x00\x00", b"\x78\x9c", b"\x78\x01", b"_unit", b"time", b"t"]
    for c in CHANNELS:
        mat_words.append(re.sub(r"[^A-Za-z0-9]", "_", c).encode())
    for u in UNITS:
        mat_words.append(u.encode("utf-16-le"))
    write_dict("mat", mat_words)
    toml_words = ["[[set]]", "\"hold\"", "\"interp\"", "\"interpolate\"", " = ", "inf", "nan", "-0.0", "1e6", "true",
                  "[rename]", "[scale]", "[unit]", "hold", "interp", ",hold,hold", ",interp,interp"]
    files = [f for fs in TOML_SEL.values() for f in fs]
    for f in files:
        text = open(os.path.join(ROOT, f), encoding="utf-8").read()
        toml_words += ["[" + m + "]" for m in re.findall(r"^\s*#?\s*\[([A-Za-z0-9_.]+)\]", text, re.M)]
        toml_words += re.findall(r"^\s*#?\s*([A-Za-z0-9_.]+)\s*=", text, re.M)
        if f.endswith(".csv"):  # map and profile headers
            toml_words += [l for l in text.splitlines() if l and not l[0].isdigit() and not l.startswith(("#", "-"))]
    write_dict("toml_files", toml_words)


def main():
    args = sys.argv[1:]
    if len(args) >= 2:
        csv_seeds(args[0], args[2] if len(args) > 2 else None)
        mat_seeds(args[1])
    else:
        print("no bench files given: csv and mat seeds not regenerated", file=sys.stderr)
    toml_seeds()
    serial_seeds()
    dicts()


if __name__ == "__main__":
    main()
