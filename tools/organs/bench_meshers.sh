#!/usr/bin/env bash
# The surface-pair mesher comparison (docs/bench_meshers.csv): gmsh (HXT) and Netgen as Lumen calls them at load against
# TetGen's command-line program (Debian's tetgen) on the same pairs, by build/lumen_bench_meshers.
#   tools/organs/bench_meshers.sh [BUILD_DIR]  (default build; needs lumen_grow_surface and lumen_bench_meshers built, and tetgen)
# Pairs: the shipped coarse aneurysm pair (data/organs), the full-resolution aneurysm with a 0.5 mm wall grown by
# lumen_grow_surface, two concentric icospheres (10 and 14 mm, 5,120 triangles each: even triangles) and two
# concentric latitude-longitude spheres (10 and 14 mm, 30 x 60 and 36 x 72: slivers at the poles).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${1:-$root/build}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$build/lumen_grow_surface" "$root/data/organs/sofa-aneurysm3D_1.off" 0.5 "$tmp/an_in.off" "$tmp/an_out.off" >&2
python3 - "$tmp" <<'PY'
import math, sys
d = sys.argv[1]
def write(name, v, f):
    with open(f"{d}/{name}", "w") as o:
        o.write(f"OFF\n{len(v)} {len(f)} 0\n")
        for x in v: o.write("%.9g %.9g %.9g\n" % tuple(x))
        for t in f: o.write("3 %d %d %d\n" % tuple(t))
def icosphere(sub, r):
    g = (1 + 5 ** 0.5) / 2
    p = [[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g], [0, -1, -g], [0, 1, -g], [g, 0, -1],
         [g, 0, 1], [-g, 0, -1], [-g, 0, 1]]
    t = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7),
         (9, 8, 1)]
    for _ in range(sub):
        mid, nt = {}, []
        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p.append([(p[a][i] + p[b][i]) / 2 for i in range(3)])
                mid[k] = len(p) - 1
            return mid[k]
        for a0, b0, c0 in t:
            a, b, c = m(a0, b0), m(b0, c0), m(c0, a0)
            nt += [(a0, a, c), (b0, b, a), (c0, c, b), (a, b, c)]
        t = nt
    return [[c * r / math.sqrt(sum(q * q for q in x)) for c in x] for x in p], t
def uv_sphere(r, rings, around):
    v = [(0, 0, -r), (0, 0, r)]
    idx = lambda k, i: 2 + k * around + i % around
    for k in range(rings):
        for i in range(around):
            phi, a = math.pi * (k + 1) / (rings + 1), 2 * math.pi * i / around
            v.append((r * math.sin(phi) * math.cos(a), r * math.sin(phi) * math.sin(a), -r * math.cos(phi)))
    f = []
    for i in range(around):
        f += [(0, idx(0, i + 1), idx(0, i)), (1, idx(rings - 1, i), idx(rings - 1, i + 1))]
        for k in range(rings - 1):
            f += [(idx(k, i), idx(k, i + 1), idx(k + 1, i + 1)), (idx(k, i), idx(k + 1, i + 1), idx(k + 1, i))]
    return v, f
write("ico_in.off", *icosphere(4, 10.0))
write("ico_out.off", *icosphere(4, 14.0))
write("uv_in.off", *uv_sphere(10.0, 30, 60))
write("uv_out.off", *uv_sphere(14.0, 36, 72))
PY
echo "pair,mesher,options,median_ms,tets,nodes,added_nodes,min_dihedral_deg,p1_dihedral_deg,p50_dihedral_deg,min_radius_ratio,p1_radius_ratio,p50_radius_ratio,degenerate_tets,volume_rel_error,keeps_input_triangles"
organs="$root/data/organs"
"$build/lumen_bench_meshers" aneurysm-coarse-0.5mm "$organs/sofa-aneurysm3D_1-coarse.off" \
  "$organs/sofa-aneurysm3D_1-coarse-outer-0.5mm.off" mm 0 gmsh:1,gmsh:0,netgen:3,netgen:1,netgen:0 3 pYQ pYQq1.414
"$build/lumen_bench_meshers" aneurysm-full-0.5mm "$tmp/an_in.off" "$tmp/an_out.off" mm 0 gmsh:1,gmsh:0,netgen:3,netgen:1,netgen:0 3 pYQ pYQq1.414
"$build/lumen_bench_meshers" icospheres-10-14mm "$tmp/ico_in.off" "$tmp/ico_out.off" mm 0 gmsh:1,gmsh:0,netgen:3,netgen:1,netgen:0 3 pYQ pYQq1.414
"$build/lumen_bench_meshers" uv-spheres-10-14mm "$tmp/uv_in.off" "$tmp/uv_out.off" mm 0 gmsh:1,gmsh:0,netgen:3,netgen:1,netgen:0 3 pYQ pYQq1.414
