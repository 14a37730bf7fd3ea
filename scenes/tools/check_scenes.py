#!/usr/bin/env python3
"""Sanity checks for the bundled scenes (stdlib only): run `python3 scenes/tools/check_scenes.py`.

For every OBJ: vertex and face counts, every face index in range, every coordinate finite,
the materials it uses defined in its MTL. For every manifest: valid JSON, only documented
fields, meshes exist. For bunny/teapot: the ground lies exactly at the model's minimum y.
"""
import json, math, os, sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
FIELDS = {"meshes", "camera", "lights", "ambient", "background", "materials", "width", "height", "spp"}

def check_obj(path):
    d = os.path.dirname(path)
    nv = 0; tris = 0; faces = 0; ys = []; mats = set(); used = set()
    for n, line in enumerate(open(path), 1):
        t = line.split()
        if not t or t[0].startswith("#"):
            continue
        if t[0] == "v":
            xyz = [float(x) for x in t[1:4]]
            assert len(xyz) == 3 and all(math.isfinite(x) for x in xyz), f"{path}:{n}: bad vertex"
            nv += 1; ys.append(xyz[1])
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) for x in t[1:]]
            assert len(idx) >= 3, f"{path}:{n}: face with {len(idx)} vertices"
            assert all(1 <= i <= nv for i in idx), f"{path}:{n}: index out of range (only backward 1-based refs used)"
            assert len(set(idx)) == len(idx), f"{path}:{n}: repeated vertex in face"
            faces += 1; tris += len(idx) - 2
        elif t[0] == "mtllib":
            for l in open(os.path.join(d, t[1])):
                if l.startswith("newmtl"):
                    mats.add(l.split()[1])
        elif t[0] == "usemtl":
            used.add(t[1])
    assert used <= mats, f"{path}: undefined materials {used - mats}"
    return nv, faces, tris, min(ys)

def main():
    ok = True
    results = {}
    for dirpath, _, files in sorted(os.walk(ROOT)):
        for f in sorted(files):
            p = os.path.join(dirpath, f)
            rel = os.path.relpath(p, ROOT)
            try:
                if f.endswith(".obj"):
                    nv, nf, nt, ymin = check_obj(p)
                    results[rel] = ymin
                    print(f"{rel}: {nv} vertices, {nf} faces, {nt} triangles, min y {ymin}")
                elif f.endswith(".json"):
                    m = json.load(open(p))
                    extra = set(m) - FIELDS
                    assert not extra, f"undocumented fields {extra}"
                    for mesh in m["meshes"]:
                        assert os.path.exists(os.path.join(dirpath, mesh)), f"missing mesh {mesh}"
                    for l in m.get("lights", []):
                        assert l["kind"] in ("point", "directional"), l
                    print(f"{rel}: JSON ok, meshes {m['meshes']}")
            except Exception as e:  # report every problem, then fail
                ok = False
                print(f"{rel}: FAIL {e}")
    for name in ("bunny", "teapot"):
        g, o = f"{name}/ground.obj", f"{name}/{name}.obj"
        if g in results and o in results and results[g] != results[o]:
            ok = False
            print(f"{g}: FAIL ground y {results[g]} != model min y {results[o]}")
    print("OK" if ok else "FAILED")
    sys.exit(0 if ok else 1)

if __name__ == "__main__":
    main()
