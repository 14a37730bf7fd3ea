#!/usr/bin/env python3
"""Independent references for `hort eval`, rendered by Mitsuba 3 under HORT's scene contract.

usage: mitsuba_refs.py OUT_DIR MANIFEST.json [MANIFEST.json ...]
       [--width W] [--height H] [--ref-spp N] [--sweep-spp 1,2,3,4,...] [--runs R]

For each manifest (docs/ARCHITECTURE.md, "Scene contract"): the same meshes, materials (MTL Kd,
then the manifest's overrides, grey 0.7 without one), pinhole camera, point and directional
lights, black background and no ambient, rendered with Mitsuba's `direct` integrator, a
`twosided(diffuse)` BSDF with albedo Kd (Mitsuba's diffuse BSDF is Kd/pi, as ours), point
emitters of radiant intensity I (irradiance I cos / r^2, as ours), and a box pixel filter of one
pixel (a pixel is the mean of its samples, as ours). Triangles whose three corners name vertex
normals (`vn`) are smooth-shaded with them, the others use their face normal, as ours. A
material's diffuse texture (`map_Kd`, PNG or JPEG) on triangles whose corners name texture
coordinates becomes a `bitmap` texture (bilinear, repeat) of Kd times the texels decoded from
sRGB to linear, as ours (OBJ's v runs up the image: Mitsuba's texture v runs down, so v is
flipped, as Mitsuba's own OBJ loader does).

Writes into OUT_DIR:
- `{scene}.pfm`: the reference, linear RGB, 32-bit PFM (rows bottom to top, as `hort` writes),
  the mean of two halves of `--ref-spp` samples each rendered with its own seed (`multijitter`);
- `mitsuba.csv`: the timed sweep, one row per scene, sampler and spp: render seconds on one
  thread (best of `--runs` after an untimed warm-up at the same spp, which compiles Dr.Jit's
  kernels; the best over `--passes` sweeps) and the error against the reference (`rmse`,
  `relmse`, `psnr`, as `hort eval` defines them: see eval/README.md);
- `floor.csv`: per scene, the reference's own error estimated from its two halves
  (|a - b| / 2 per value: the RMSE of their mean when their errors are independent);
- `settings.json`: every setting above plus Mitsuba's, Dr.Jit's and Python's versions.

Every error names the file and line it comes from.
"""
import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

SAMPLERS = ("independent", "multijitter")
REF_SEEDS = (1001, 2002)
SWEEP_SEED = 1
WARMUP_SEED = 7
# relMSE's denominator guard: (x - r)^2 / (r^2 + RELMSE_EPS), the same constant in src/eval.
RELMSE_EPS = 1e-2


def fail(msg):
    sys.exit(f"error: {msg}")


def parse_mtl(path, where):
    """Diffuse colour and texture file (or None) by material name."""
    kd, name = {}, None
    try:
        lines = open(path).read().splitlines()
    except OSError as e:
        fail(f"{where}: cannot read {path}: {e.strerror}")
    for n, line in enumerate(lines, 1):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "newmtl":
            name = parts[1]
            kd.setdefault(name, {"kd": [0.7, 0.7, 0.7], "map": None})
        elif parts[0] == "Kd":
            if name is None:
                fail(f"{path}:{n}: Kd before any newmtl")
            values = [float(v) for v in parts[1:4]]
            kd[name]["kd"] = values * 3 if len(values) == 1 else values
        elif parts[0] == "map_Kd":
            if name is None:
                fail(f"{path}:{n}: map_Kd before any newmtl")
            # Options come first; the file is the last word, relative to the library's folder.
            if kd[name]["map"] is None:
                kd[name]["map"] = os.path.join(os.path.dirname(path), parts[-1])
    return kd


def parse_obj(path):
    """Positions (float64), normals, texture coordinates, and triangles grouped by material name
    (None: no material), each triangle three (position, texcoord or -1, normal or -1) corners."""
    positions, normals, texcoords, groups, kd, material = [], [], [], {}, {}, None
    try:
        lines = open(path).read().splitlines()
    except OSError as e:
        fail(f"cannot read {path}: {e.strerror}")
    for n, line in enumerate(lines, 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        key = parts[0]
        if key == "v":
            positions.append([float(v) for v in parts[1:4]])
        elif key == "vn":
            normals.append([float(v) for v in parts[1:4]])
        elif key == "vt":
            texcoords.append([float(v) for v in (parts[1:3] + ["0"])[:2]])
        elif key == "f":
            def index(word, count):
                if not word:
                    return -1
                i = int(word)
                return i - 1 if i > 0 else count + i
            idx = []
            for token in parts[1:]:
                words = (token.split("/") + ["", ""])[:3]
                idx.append((index(words[0], len(positions)), index(words[1], len(texcoords)),
                            index(words[2], len(normals))))
            for i in range(1, len(idx) - 1):  # fan triangulation (0, i, i+1), as ours
                groups.setdefault(material, []).append([idx[0], idx[i], idx[i + 1]])
        elif key == "usemtl":
            material = parts[1]
        elif key == "mtllib":
            kd.update(parse_mtl(os.path.join(os.path.dirname(path), parts[1]), f"{path}:{n}"))
    return (np.array(positions, dtype=np.float64), np.array(normals, dtype=np.float32).reshape(-1, 3),
            np.array(texcoords, dtype=np.float32).reshape(-1, 2), groups, kd)


def grey(value, where):
    if isinstance(value, (int, float)):
        return [float(value)] * 3
    if isinstance(value, list) and len(value) == 3:
        return [float(v) for v in value]
    fail(f"{where}: expected a number or three numbers, got {value!r}")


def load_manifest(path):
    """(name, meshes, camera, lights, overrides, origin); origin centres the scene as ours does."""
    with open(path) as fh:
        m = json.load(fh)
    if grey(m.get("ambient", 0.0), f"{path}: ambient") != [0.0] * 3:
        fail(f"{path}: ambient is not 0: Mitsuba's direct integrator has no ambient term")
    if grey(m.get("background", 0.0), f"{path}: background") != [0.0] * 3:
        fail(f"{path}: background is not black: not modelled by these references")
    if "camera" not in m or "lights" not in m:
        fail(f"{path}: needs its own camera and lights (the default framing is not reproduced here)")
    base = os.path.dirname(path)
    meshes = [parse_obj(os.path.join(base, name)) for name in m["meshes"]]
    overrides = {k: grey(v["kd"], f"{path}: materials.{k}.kd") for k, v in m.get("materials", {}).items()}
    name = os.path.splitext(os.path.basename(path))[0]
    return name, meshes, m["camera"], m["lights"], overrides


def reflectance(mi, colour, texture, cache):
    """Kd, or Kd times the texture (linear, bilinear, repeat) when there is one."""
    if texture is None:
        return {"type": "rgb", "value": colour}
    key = (texture, tuple(colour))
    if key not in cache:
        if not os.path.isfile(texture):
            fail(f"{texture}: texture file not found")
        linear = mi.Bitmap(texture).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32,
                                             srgb_gamma=False)
        data = np.array(linear, dtype=np.float32) * np.array(colour, dtype=np.float32)
        cache[key] = mi.Bitmap(np.ascontiguousarray(data))
    return {"type": "bitmap", "bitmap": cache[key], "raw": True,
            "filter_type": "bilinear", "wrap_mode": "repeat"}


def build_scene(mi, manifest, width, height, sampler, spp, seed):
    _, meshes, camera, lights, overrides = manifest
    all_pos = np.concatenate([m[0] for m in meshes])
    # Everything is moved by the bounding box centre (in float64) before rounding to float32,
    # as our loader does, so both renderers see the same float32 geometry.
    lo, hi = all_pos.min(axis=0), all_pos.max(axis=0)
    origin = 0.5 * (lo + hi)
    T = mi.ScalarTransform4f
    up = camera.get("up", [0.0, 1.0, 0.0])
    eye = (np.array(camera["eye"], float) - origin).tolist()
    target = (np.array(camera["look_at"], float) - origin).tolist()
    d = {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "perspective", "fov": float(camera.get("vfov", 45.0)), "fov_axis": "y",
            "near_clip": 1e-4, "far_clip": 1e7,
            "to_world": T().look_at(origin=eye, target=target, up=up),
            "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": sampler, "sample_count": spp, "seed": seed},
        },
    }
    count, textures = 0, {}
    for positions, normals, texcoords, groups, library in meshes:
        for material, tris in groups.items():
            entry = library.get(material, {"kd": [0.7, 0.7, 0.7], "map": None})
            colour = overrides.get(material if material is not None else "default", entry["kd"])
            # As our loader: normals only where all three corners name one, texture coordinates
            # only where all three do and the material has a texture.
            classes = {}
            for tri in tris:
                smooth = all(c[2] >= 0 for c in tri)
                textured = entry["map"] is not None and all(c[1] >= 0 for c in tri)
                classes.setdefault((smooth, textured), []).append(tri)
            for (smooth, textured), group in sorted(classes.items()):
                # One Mitsuba vertex per distinct corner (position, texcoord, normal) used.
                corners, faces = {}, []
                for tri in group:
                    face = []
                    for p, t, n in tri:
                        key = (p, t if textured else -1, n if smooth else -1)
                        face.append(corners.setdefault(key, len(corners)))
                    faces.append(face)
                keys = list(corners)
                props = mi.Properties()
                props["bsdf"] = mi.load_dict({"type": "twosided", "material": {
                    "type": "diffuse",
                    "reflectance": reflectance(mi, colour, entry["map"] if textured else None, textures)}})
                mesh = mi.Mesh(f"m{count}", len(keys), len(faces), props,
                               has_vertex_normals=smooth, has_vertex_texcoords=textured)
                params = mi.traverse(mesh)
                at = np.array([k[0] for k in keys])
                params["vertex_positions"] = mi.Float((positions[at] - origin).astype(np.float32).ravel())
                params["faces"] = mi.UInt32(np.array(faces, dtype=np.uint32).ravel())
                if smooth:
                    params["vertex_normals"] = mi.Float(normals[[k[2] for k in keys]].ravel())
                if textured:
                    uv = texcoords[[k[1] for k in keys]].copy()
                    uv[:, 1] = 1.0 - uv[:, 1]
                    params["vertex_texcoords"] = mi.Float(uv.ravel())
                params.update()
                d[f"mesh{count}"] = mesh
                count += 1
    for i, light in enumerate(lights):
        kind = light.get("kind")
        if kind == "point":
            d[f"light{i}"] = {"type": "point",
                              "position": (np.array(light["position"], float) - origin).tolist(),
                              "intensity": {"type": "rgb", "value": grey(light["intensity"], "intensity")}}
        elif kind == "directional":
            d[f"light{i}"] = {"type": "directional", "direction": light["direction"],
                              "irradiance": {"type": "rgb", "value": grey(light["irradiance"], "irradiance")}}
        else:
            fail(f"lights[{i}]: unknown kind {kind!r}")
    return mi.load_dict(d)


def render(mi, dr, scene, spp, seed):
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return np.array(img, dtype=np.float64)


def metrics(x, r):
    d2 = (x - r) ** 2
    mse = float(d2.mean())
    rmse = math.sqrt(mse)
    relmse = float((d2 / (r * r + RELMSE_EPS)).mean())
    psnr = math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)
    return rmse, relmse, psnr


def read_pfm(path):
    try:
        data = open(path, "rb").read()
    except OSError as e:
        fail(f"cannot read {path}: {e.strerror}")
    head = data.split(b"\n", 3)
    if len(head) != 4 or head[0] != b"PF" or head[2] != b"-1.0":
        fail(f"{path}: not a little-endian RGB PFM as this script writes")
    w, h = map(int, head[1].split())
    return np.frombuffer(head[3], "<f4").reshape(h, w, 3)[::-1].astype(np.float64)


def write_pfm(path, img):
    h, w, _ = img.shape
    with open(path + ".tmp", "wb") as fh:
        fh.write(f"PF\n{w} {h}\n-1.0\n".encode())
        fh.write(np.ascontiguousarray(img[::-1].astype("<f4")).tobytes())
    os.replace(path + ".tmp", path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out_dir")
    ap.add_argument("manifests", nargs="+")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--sweep-spp", default="1,2,3,4,6,8,12,16,24,32,48,64,96,128,192,256")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--passes", type=int, default=2,
                    help="sweeps of every setting, each its best of --runs; the best counts")
    ap.add_argument("--reuse-references", action="store_true",
                    help="keep OUT_DIR's references and floor.csv; run the timed sweep only")
    ap.add_argument("--ref-threads", type=int, default=0, help="threads of the reference render (0: all)")
    a = ap.parse_args()
    sweep = [int(s) for s in a.sweep_spp.split(",")]
    if a.ref_spp % 2:
        fail(f"--ref-spp {a.ref_spp}: must be even (two halves)")
    # Dr.Jit caches compiled kernels under HOME: keep them out of the user's home folder.
    os.environ["HOME"] = os.environ.get("HORT_MITSUBA_HOME", os.path.join(a.out_dir, ".home"))
    import drjit as dr
    import mitsuba as mi
    # The LLVM backend (vectorised, JIT-compiled) is Mitsuba's fast CPU path and the one the
    # issue's figures used; `scalar_rgb` is several times slower per sample.
    variant = "llvm_ad_rgb"
    mi.set_variant(variant)
    all_threads = dr.thread_count()
    os.makedirs(a.out_dir, exist_ok=True)
    rows, floors, ref_taken = [], [], 0
    for path in a.manifests:
        manifest = load_manifest(path)
        name = manifest[0]
        if a.reuse_references:
            ref = read_pfm(os.path.join(a.out_dir, f"{name}.pfm"))
            if ref.shape != (a.height, a.width, 3):
                fail(f"{name}.pfm: {ref.shape[1]}x{ref.shape[0]}, not {a.width}x{a.height}")
        else:
            dr.set_thread_count(a.ref_threads or all_threads)
            half = a.ref_spp // 2
            halves = []
            for seed in REF_SEEDS:
                scene = build_scene(mi, manifest, a.width, a.height, "multijitter", half, seed)
                ref_taken = scene.sensors()[0].sampler().sample_count()
                halves.append(render(mi, dr, scene, ref_taken, seed))
            # Errors are measured against the stored float32 values, as `hort eval` reads them.
            ref = (0.5 * (halves[0] + halves[1])).astype(np.float32).astype(np.float64)
            write_pfm(os.path.join(a.out_dir, f"{name}.pfm"), ref)
            diff = 0.5 * (halves[0] - halves[1])
            floor_rmse = math.sqrt(float((diff ** 2).mean()))
            floors.append((name, floor_rmse, 10 * math.log10(1 / floor_rmse ** 2)))
            print(f"{name}: reference 2 x {ref_taken} spp, own RMSE ~{floor_rmse:.3e}", file=sys.stderr)
        dr.set_thread_count(1)
        # The whole sweep `--passes` times, each setting's runs in a row after a warm-up (runs
        # of different settings interleaved cost Dr.Jit 10 to 30 ms a render that a single
        # render never pays); a setting keeps its best over the passes, so that a slow minute
        # of a shared machine costs it at most one pass.
        best = {}
        for _ in range(a.passes):
            for sampler in SAMPLERS:
                for spp in sweep:
                    scene = build_scene(mi, manifest, a.width, a.height, sampler, spp, SWEEP_SEED)
                    # multijitter rounds the count up to a grid it can stratify (e.g. 32 -> 35):
                    # the CSV records the count actually taken.
                    taken = scene.sensors()[0].sampler().sample_count()
                    render(mi, dr, scene, taken, WARMUP_SEED)
                    seconds = best.get((sampler, spp), (math.inf,))[0]
                    for _ in range(a.runs):
                        t0 = time.perf_counter()
                        img = render(mi, dr, scene, taken, SWEEP_SEED)
                        seconds = min(seconds, time.perf_counter() - t0)
                    best[(sampler, spp)] = (seconds, img, taken)
        for sampler in SAMPLERS:
            for spp in sweep:
                seconds, img, taken = best[(sampler, spp)]
                rmse, relmse, psnr = metrics(img, ref)
                rows.append((name, sampler, taken, seconds, rmse, relmse, psnr))
                print(f"{name} {sampler} {taken:4d} spp {seconds:8.4f} s psnr {psnr:6.2f}",
                      file=sys.stderr)
    dr.set_thread_count(all_threads)
    with open(os.path.join(a.out_dir, "mitsuba.csv"), "w") as fh:
        fh.write("scene,sampler,spp,seconds,rmse,relmse,psnr\n")
        for r in rows:
            fh.write(f"{r[0]},{r[1]},{r[2]},{r[3]:.6f},{r[4]:.6e},{r[5]:.6e},{r[6]:.4f}\n")
    if not a.reuse_references:
        with open(os.path.join(a.out_dir, "floor.csv"), "w") as fh:
            fh.write("scene,rmse,psnr\n")
            for r in floors:
                fh.write(f"{r[0]},{r[1]:.6e},{r[2]:.4f}\n")
    settings = {
        "renderer": "Mitsuba 3", "mitsuba": mi.__version__, "drjit": dr.__version__,
        "python": platform.python_version(), "variant": variant,
        "variant_why": "LLVM backend: Mitsuba's fast CPU path, the one the issue's figures used",
        "cpu": platform.processor() or platform.machine(),
        "integrator": "direct (defaults: 1 emitter sample, 1 BSDF sample per hit)",
        "bsdf": "twosided(diffuse), reflectance = Kd (manifest override, else MTL, else 0.7)",
        "emitters": "point (intensity = manifest W/sr), directional (irradiance)",
        "rfilter": "box (radius 0.5 px)", "sensor": "perspective, fov_axis y, look_at(eye, look_at, up)",
        "normals": "vertex normals where a triangle's three corners name one, else face normals",
        "textures": "map_Kd as a bitmap (bilinear, repeat, raw) of Kd times the sRGB-decoded texels",
        "origin": "geometry moved by its bounding box centre (float64) before float32",
        "width": a.width, "height": a.height,
        "reference": {"sampler": "multijitter", "spp": a.ref_spp, "halves_seeds": list(REF_SEEDS),
                      "spp_taken": 2 * ref_taken,
                      "threads": a.ref_threads or all_threads},
        "sweep": {"samplers": list(SAMPLERS), "spp": sweep, "seed": SWEEP_SEED, "threads": 1,
                  "timing": f"best of {a.runs} after an untimed warm-up render (seed {WARMUP_SEED}), "
                            f"best over {a.passes} passes of the sweep"},
        "metrics": {"relmse_eps": RELMSE_EPS, "psnr_peak": 1.0},
        "scenes": [os.path.relpath(p, a.out_dir) for p in a.manifests],
    }
    if a.reuse_references:
        with open(os.path.join(a.out_dir, "settings.json")) as fh:
            settings["reference"] = json.load(fh)["reference"]
    with open(os.path.join(a.out_dir, "settings.json"), "w") as fh:
        json.dump(settings, fh, indent=2)
        fh.write("\n")


if __name__ == "__main__":
    main()
