#!/usr/bin/env python3
"""Writes the fuzz seeds under tests/fuzz/inputs/<reader>/seed-*: small valid files of every format Lumen reads,
each of which the regression test (tests/engine/test_fuzz_inputs.cpp) checks reads, and from which tools/fuzz.sh
starts. Small, so that the fuzzer's mutations stay fast: a few of the shipped scenes; a 6-point centreline with
and without its frames; a closed octahedron in OBJ, ASCII and binary STL, ASCII and binary PLY, and OFF; a
hollow tube of 8 x 2 x 1 cells (Lumen's own mesher, exported by lumen run --export-volume) as gmsh MSH 2.2 and
4.1 with tagged walls, and VTK .vtu and legacy .vtk without tags; a replay, a pose track and CCD queries.

Usage (Debian's python3-meshio): /usr/bin/python3 tests/fuzz/make_seeds.py build/lumen
"""
import json
import os
import shutil
import struct
import sys

import meshio
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import make_volume_tube  # noqa: E402  (rest_mesh, boundary)

INPUTS = os.path.join(ROOT, "tests", "fuzz", "inputs")
SCENES = ["paper-press.json", "twist-linear.json", "instrument-probe-press.json", "fig5-squeeze.json"]
# A closed octahedron, triangles counter-clockwise seen from outside (millimetres).
OCTA_POINTS = [(10, 0, 0), (-10, 0, 0), (0, 10, 0), (0, -10, 0), (0, 0, 10), (0, 0, -10)]
OCTA_TRIS = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
# The seed tube: few enough cells for small files, 8 around so its walls split into patches (kFeatureAngleDeg).
TUBE = {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.02,
        "segments_around": 8, "segments_along": 2, "layers": 1}


def put(reader, name, data):
    folder = os.path.join(INPUTS, reader)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def centrelines():
    s = np.linspace(0.0, 50.0, 6)
    points = [[float(v), float(np.sin(v / 20.0) * 5.0), 0.0] for v in s]
    put("centreline", "seed-points.json", json.dumps({"n": 6, "points": points}))
    tangents, normals = [], []
    for v in s:
        t = np.array([1.0, np.cos(v / 20.0) * 0.25, 0.0])
        t /= np.linalg.norm(t)
        tangents.append(t.tolist())
        normals.append([0.0, 0.0, 1.0])
    put("centreline", "seed-frames.json", json.dumps({"n": 6, "points": points, "tangents": tangents,
                                                      "normals": normals}))


def surfaces():
    p, t = OCTA_POINTS, OCTA_TRIS
    put("obj", "seed.obj", "".join(f"v {x} {y} {z}\n" for x, y, z in p) +
        "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in t))
    put("off", "seed.off", f"OFF\n{len(p)} {len(t)} 0\n" + "".join(f"{x} {y} {z}\n" for x, y, z in p) +
        "".join(f"3 {a} {b} {c}\n" for a, b, c in t))
    ply_head = (f"ply\nformat {{}} 1.0\nelement vertex {len(p)}\nproperty float x\nproperty float y\n"
                f"property float z\nelement face {len(t)}\nproperty list uchar int vertex_indices\nend_header\n")
    put("ply", "seed-ascii.ply", ply_head.format("ascii") + "".join(f"{x} {y} {z}\n" for x, y, z in p) +
        "".join(f"3 {a} {b} {c}\n" for a, b, c in t))
    put("ply", "seed-binary.ply", ply_head.format("binary_little_endian").encode() +
        b"".join(struct.pack("<3f", *v) for v in p) + b"".join(struct.pack("<B3i", 3, *f) for f in t))
    facets = []
    for a, b, c in t:
        n = np.cross(np.subtract(p[b], p[a]), np.subtract(p[c], p[a]))
        facets.append((n / np.linalg.norm(n), p[a], p[b], p[c]))
    put("stl", "seed-ascii.stl", "solid octa\n" + "".join(
        f"facet normal {n[0]} {n[1]} {n[2]}\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in (a, b, c))
        + "endloop\nendfacet\n" for n, a, b, c in facets) + "endsolid octa\n")
    put("stl", "seed-binary.stl", b"octa".ljust(80, b" ") + struct.pack("<I", len(facets)) + b"".join(
        struct.pack("<12fH", *n, *a, *b, *c, 0) for n, a, b, c in facets))


def msh41(points, tets, tris, tags):
    """gmsh MSH 4.1 ASCII (meshio needs entity data for it): one surface entity per wall tag, one volume entity."""
    names = sorted(make_volume_tube.TAGS.items(), key=lambda kv: kv[1])
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names) + 1)]
    out += [f'2 {tag} "{name}"' for name, tag in names] + ['3 4 "wall"', "$EndPhysicalNames", "$Entities",
                                                           f"0 0 {len(names)} 1"]
    out += [f"{tag} 0 0 0 1 1 1 1 {tag} 0" for _, tag in names]
    out += ["1 0 0 0 1 1 1 1 4 " + " ".join([str(len(names))] + [str(tag) for _, tag in names]), "$EndEntities"]
    n = len(points)
    out += ["$Nodes", f"1 {n} 1 {n}", f"3 1 0 {n}"] + [str(i + 1) for i in range(n)]
    out += [" ".join(repr(float(c)) for c in p) for p in points] + ["$EndNodes"]
    blocks = [(2, tag, tris[tags == tag]) for _, tag in names] + [(3, 1, tets)]
    total = len(tris) + len(tets)
    out += ["$Elements", f"{len(blocks)} {total} 1 {total}"]
    element = 1
    for dim, entity, rows in blocks:
        out.append(f"{dim} {entity} {2 if dim == 2 else 4} {len(rows)}")
        for r in rows:
            out.append(" ".join([str(element)] + [str(int(v) + 1) for v in r]))
            element += 1
    return "\n".join(out + ["$EndElements", ""])


def volumes(lumen):
    scene = json.load(open(os.path.join(ROOT, "scenes", "paper-press.json")))
    scene["mesh"] = TUBE
    scene["probes"][0]["point"] = [0.0, TUBE["outer_radius"], TUBE["length"] / 2]
    points, tets = make_volume_tube.rest_mesh(lumen, scene)
    tris = make_volume_tube.boundary(tets, points)
    radius = np.hypot(points[:, 0], points[:, 1])
    tags = np.full(len(tris), make_volume_tube.TAGS["ends"])
    for name in ("inner", "outer"):
        on_wall = np.abs(radius - TUBE[name + "_radius"]) < make_volume_tube.RADIUS_TOLERANCE
        tags[on_wall[tris].all(axis=1)] = make_volume_tube.TAGS[name]
    mm = np.round(points * make_volume_tube.MM_PER_M, 9)
    tagged = meshio.Mesh(
        mm, [("triangle", tris), ("tetra", tets)],
        cell_data={"gmsh:physical": [tags, np.full(len(tets), 4)], "gmsh:geometrical": [tags, np.full(len(tets), 1)]},
        field_data={**{n: np.array([g, 2]) for n, g in make_volume_tube.TAGS.items()}, "wall": np.array([4, 3])})
    plain = meshio.Mesh(mm, [("tetra", tets)])
    tmp = os.path.join(INPUTS, "tmp")
    os.makedirs(tmp, exist_ok=True)
    put("msh", "seed-41.msh", msh41(mm, tets, tris, tags))
    for reader, name, mesh, fmt in (("msh", "seed-22.msh", tagged, "gmsh22"),
                                    ("vtu", "seed.vtu", plain, "vtu"), ("vtk", "seed.vtk", plain, "vtk")):
        path = os.path.join(tmp, name)
        mesh.write(path, file_format=fmt, binary=False)
        put(reader, name, open(path, "rb").read())
    shutil.rmtree(tmp)


def tables():
    put("replay", "seed.csv", "t,x,y,z,fx,fy,fz\n# a probe pressed and released\n"
        "0,0,0.013,0.05,0,0,0\n0.5,0,0.013,0.05,0,-0.01,0\n1,0,0.013,0.05,0,0,0\n")
    put("pose", "seed.csv", "t,x,y,z,qw,qx,qy,qz\n0,0,0.02,0.05,1,0,0,0\n"
        "0.5,0,0.015,0.05,0.9238795325112867,0.3826834323650898,0,0\n1,0,0.013,0.05,0.7071067811865476,0.7071067811865476,0,0\n")
    with open(os.path.join(ROOT, "tests", "data", "ccd", "handcrafted.csv")) as f:
        lines = f.readlines()
    vf = [l for l in lines if l.startswith("vf,")][:2]
    ee = [l for l in lines if l.startswith("ee,")][:2]
    put("ccd", "seed.csv", "".join(lines[:2] + vf + ee))


def main():
    lumen = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "lumen")
    for name in SCENES:
        put("scene", "seed-" + name, open(os.path.join(ROOT, "scenes", name), "rb").read())
    centrelines()
    surfaces()
    volumes(lumen)
    tables()


if __name__ == "__main__":
    main()
