#!/usr/bin/env python3
"""How well 2D pixel samplers integrate an edge: the error behind docs/perf/sampling.md.

usage: sampler_edges.py [TRIALS] [COUNTS]      (defaults: 3000, 3,4,6,12,16,24,32,48,64,96,128,256)
needs numpy (the Mitsuba venv of eval/references.sh has it: target/mitsuba-venv/bin/python)

Each trial is a pixel crossed by a straight edge (a random point and angle): the exact covered
area against the mean of n samples, each trial with its own random pattern. Prints the PSNR of
that estimate (10 log10(1 / MSE)) by sample count for:
- cmj: correlated multi-jittered (Kensler 2013) on the m x ceil(n/m) grid, m = floor(sqrt(n)),
  samples past n dropped: the renderer's sampler before, and Mitsuba 3's `multijitter`
  (which rounds n up to the full grid instead);
- owen: the 2D Sobol sequence with hash-based Owen scrambling (Laine-Karras, Burley 2020), as
  core/src/sampling/sobol.rs computes it: the renderer's sampler now;
- matousek: the same points with a random linear scramble and digital shift instead;
- r2: Roberts' R2 sequence with a random toroidal shift.
Deterministic (fixed seed).
"""
import math
import sys

import numpy as np

M32 = np.uint64(0xFFFFFFFF)
rng = np.random.default_rng(1)


def u32(a):
    return np.asarray(a, dtype=np.uint64) & M32


def reverse(v):
    v, r = u32(v), np.zeros_like(u32(v))
    for b in range(32):
        r |= ((v >> np.uint64(b)) & np.uint64(1)) << np.uint64(31 - b)
    return r


def laine_karras(v, seed):
    v = (u32(v) + seed) & M32
    for c in (0x6C50B47C, 0xB82F1E52, 0xC7AFE638, 0x8D22F6E6):
        v ^= (v * np.uint64(c)) & M32
    return v


def second_dimension_reversed(i):
    i, out, v = u32(i), np.zeros_like(u32(i)), np.uint64(1)
    for b in range(32):
        out ^= np.where(((i >> np.uint64(b)) & np.uint64(1)) == 1, v, np.uint64(0))
        v = (v ^ (v << np.uint64(1))) & M32
    return out


def unit(v):
    return (v >> np.uint64(8)) / 2.0**24


def indices(n, trials):
    return np.broadcast_to(u32(np.arange(n))[None, :], (trials, n))


def owen(n, trials):
    sx, sy = (u32(rng.integers(0, 2**32, trials))[:, None] for _ in range(2))
    i = indices(n, trials)
    return unit(reverse(laine_karras(i, sx))), unit(reverse(laine_karras(second_dimension_reversed(i), sy)))


def matousek(n, trials):
    i = indices(n, trials)
    out = []
    for v in (reverse(i), reverse(second_dimension_reversed(i))):
        res = np.zeros_like(v)
        for t in range(trials):
            lower = np.tril(rng.integers(0, 2, (32, 32)), -1) + np.eye(32, dtype=np.int64)
            bits = ((v[t][:, None] >> np.uint64(31 - np.arange(32))) & np.uint64(1)).astype(np.int64)
            scrambled = ((bits @ lower.T) % 2).astype(np.uint64)
            res[t] = (scrambled << np.uint64(31 - np.arange(32))).sum(1).astype(np.uint64)
        out.append(unit(res ^ u32(rng.integers(0, 2**32, trials))[:, None]))
    return out[0], out[1]


def cmj(n, trials):
    m = math.isqrt(n)
    rows = -(-n // m)
    xs, ys = np.zeros((trials, n)), np.zeros((trials, n))
    s = np.arange(n)
    col, row = s % m, s // m
    for t in range(trials):
        px, py = rng.permutation(m), rng.permutation(rows)
        jx, jy = rng.random(n), rng.random(n)
        xs[t] = (col + (py[row] + jx) / rows) / m
        ys[t] = (row + (px[col] + jy) / m) / rows
    return xs, ys


def r2(n, trials):
    g = 1.32471795724474602596
    i = np.arange(n)[None, :]
    return (rng.random((trials, 1)) + i / g) % 1, (rng.random((trials, 1)) + i / (g * g)) % 1


def covered_area(px, py, angle):
    """Area of the unit square where (x - px) cos a + (y - py) sin a > 0 (polygon clipping)."""
    c, s = math.cos(angle), math.sin(angle)
    square = [(0, 0), (1, 0), (1, 1), (0, 1)]
    side = lambda p: (p[0] - px) * c + (p[1] - py) * s
    kept = []
    for k in range(4):
        p, q = square[k], square[(k + 1) % 4]
        fp, fq = side(p), side(q)
        if fp > 0:
            kept.append(p)
        if (fp > 0) != (fq > 0):
            t = fp / (fp - fq)
            kept.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    area = sum(kept[k][0] * kept[(k + 1) % len(kept)][1] - kept[(k + 1) % len(kept)][0] * kept[k][1]
               for k in range(len(kept)))
    return abs(area) / 2


def main():
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
    counts = [int(v) for v in (sys.argv[2] if len(sys.argv) > 2 else "3,4,6,12,16,24,32,48,64,96,128,256").split(",")]
    edges = np.array([(rng.random(), rng.random(), rng.random() * 2 * math.pi) for _ in range(trials)])
    exact = np.array([covered_area(*e) for e in edges])
    samplers = {"cmj": cmj, "owen": owen, "matousek": matousek, "r2": r2}
    print("spp   " + "  ".join(f"{k:>8}" for k in samplers))
    for n in counts:
        row = []
        for make in samplers.values():
            x, y = make(n, trials)
            inside = (x - edges[:, 0:1]) * np.cos(edges[:, 2:3]) + (y - edges[:, 1:2]) * np.sin(edges[:, 2:3]) > 0
            row.append(10 * math.log10(1 / ((inside.mean(1) - exact) ** 2).mean()))
        print(f"{n:<5} " + "  ".join(f"{r:8.2f}" for r in row))


if __name__ == "__main__":
    main()
