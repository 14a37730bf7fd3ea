#!/usr/bin/env python3
"""Ours next to Mitsuba's reference, as one PNG, with the PSNR between them.

usage: side_by_side.py OURS.pfm REFERENCE.pfm OUT.png

Both are linear RGB PFMs of the same size (as `hort render --out x.pfm` and mitsuba_refs.py
write them). The PNG holds ours on the left and the reference on the right, each converted to
8-bit sRGB as `hort` converts (clamped to [0, 1], IEC 61966-2-1, rounded), with a 4-pixel black
gap. Prints `psnr DB rmse R max M` (peak 1, over every value, as `hort eval` measures).
"""
import math
import struct
import sys
import zlib

import numpy as np


def read_pfm(path):
    data = open(path, "rb").read()
    head = data.split(b"\n", 3)
    if len(head) != 4 or head[0] != b"PF" or head[2] != b"-1.0":
        sys.exit(f"error: {path}: not a little-endian RGB PFM")
    w, h = map(int, head[1].split())
    return np.frombuffer(head[3], "<f4").reshape(h, w, 3)[::-1].astype(np.float64)


def srgb8(x):
    x = np.clip(x, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255).astype(np.uint8)


def write_png(path, rgb):
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))

    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    ours, ref = read_pfm(sys.argv[1]), read_pfm(sys.argv[2])
    if ours.shape != ref.shape:
        sys.exit(f"error: sizes differ: {ours.shape[1]}x{ours.shape[0]} and {ref.shape[1]}x{ref.shape[0]}")
    mse = float(((ours - ref) ** 2).mean())
    h, w, _ = ours.shape
    out = np.zeros((h, 2 * w + 4, 3), dtype=np.uint8)
    out[:, :w] = srgb8(ours)
    out[:, w + 4:] = srgb8(ref)
    write_png(sys.argv[3], out)
    psnr = math.inf if mse == 0 else 10 * math.log10(1 / mse)
    print(f"psnr {psnr:.2f} rmse {math.sqrt(mse):.3e} max {np.abs(ours - ref).max():.3e}")


if __name__ == "__main__":
    main()
