"""Throughput of the Tekscan ASCII import and of MCAP recordings: prints a table of frames/s.

Run: ``.venv/bin/python benchmarks/tekscan_import.py [--quick]``. A synthetic export (seeded) is written to a
temporary folder: a hand-sized map (44x44, ``B`` outside a rounded sensor outline, CRLF) and a 4x4 pad, each in the
classic and the newer ``Frame N, t, ...`` variant. Measured: parse only (:func:`read_tekscan`), parse + region +
MCAP write (:func:`import_tekscan`), and reading the MCAP back (:func:`read_recording`). Best of 3 runs.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from palpate.core.io.mcap_reader import read_recording
from palpate.hardware.tekscan.importer import import_tekscan
from palpate.hardware.tekscan.reader import read_tekscan


def write_export(path: Path, frames: int, rows: int, cols: int, variant: str, rng: np.random.Generator) -> None:
    yy, xx = np.mgrid[:rows, :cols]
    outside = ((yy - rows / 2 + 0.5) ** 2 + (xx - cols / 2 + 0.5) ** 2) > (0.55 * max(rows, cols)) ** 2
    head = (f"DATA_TYPE MOVIE\nROWS {rows}\nCOLS {cols}\nROW_SPACING 0.254 cm\nCOL_SPACING 0.254 cm\n"
            f"SENSEL_AREA 0.0645 sq cm\nNOISE_THRESHOLD 3\nSECONDS_PER_FRAME 0.01\nSTART_FRAME 1\n"
            f"END_FRAME {frames}\nUNITS RAW\nASCII_DATA @@\n")
    parts = [head]
    for k in range(frames):
        counts = rng.integers(0, 256, (rows, cols)).astype(str).astype(object)
        counts[outside] = "B"
        line = f"Frame {k + 1}" if variant == "classic" else f"Frame {k + 1}, {0.01 * k:.3f}, 0, 0"
        parts.append("\n" + line + "\n" + "\n".join(",".join(r) for r in counts) + "\n")
    path.write_text("".join(parts).replace("\n", "\r\n"), newline="")


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames (a few seconds in all)")
    args = ap.parse_args()
    rng = np.random.default_rng(12345)
    n_hand, n_pad = (300, 5000) if args.quick else (2000, 30000)
    cases = [("hand 44x44", 44, 44, n_hand, "10:14,20:24"), ("pad 4x4", 4, 4, n_pad, None)]
    print(f"{'map':<11} {'variant':<8} {'frames':>7} {'MB':>6} {'parse f/s':>10} {'Mvalues/s':>10} "
          f"{'import f/s':>11} {'read f/s':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for label, rows, cols, n, region in cases:
            for variant in ("classic", "new"):
                src = Path(tmp) / f"{label[:4]}_{variant}.csv"
                out = Path(tmp) / f"{label[:4]}_{variant}.mcap"
                write_export(src, n, rows, cols, variant, rng)
                t_parse = best_of(lambda src=src: read_tekscan(src))
                t_import = best_of(lambda src=src, out=out, region=region: import_tekscan(src, out, region=region))
                t_read = best_of(lambda out=out: read_recording(out))
                print(f"{label:<11} {variant:<8} {n:>7} {src.stat().st_size / 1e6:>6.1f} {n / t_parse:>10.0f} "
                      f"{n * rows * cols / t_parse / 1e6:>10.2f} {n / t_import:>11.0f} {n / t_read:>9.0f}")
    print("import = parse + region (4x4) + MCAP write; read = read_recording of that MCAP (validates every message)")


if __name__ == "__main__":
    main()
