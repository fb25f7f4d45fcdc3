#!/usr/bin/env python3
"""gen_many.py — writes a many-light test scene: a floor, twelve diffuse spheres and a ceiling
panel of N small emitting triangles facing down (binary PLY), seen by a perspective camera.

The emitters' total power does not depend on N (each triangle's radiance is scaled by 1/N), so
images at different N look alike and their costs can be compared. Emitter positions are jittered
on a grid with a fixed seed; the scene is a function of (N, seed) only.

    bench/ias/gen_many.py N OUT_DIR [--seed S] [--resolution R]

writes OUT_DIR/many-N.pbrt and OUT_DIR/many-N-emitters.ply.
"""
import argparse
import math
import os
import random
import struct


def write_emitters(path, n, rng):
    side = int(math.ceil(math.sqrt(n)))
    cell = 8.0 / side
    size = 0.35 * cell  # each triangle covers about 1/16 of its cell: gaps between emitters
    verts = []
    for i in range(n):
        gx, gz = i % side, i // side
        cx = -4.0 + (gx + 0.5) * cell + rng.uniform(-0.2, 0.2) * cell
        cz = -4.0 + (gz + 0.5) * cell + rng.uniform(-0.2, 0.2) * cell
        a = rng.uniform(0.0, 2.0 * math.pi)
        for k in range(3):
            t = a + k * 2.0 * math.pi / 3.0
            verts.append((cx + size * math.cos(t), 3.98, cz + size * math.sin(t)))
    with open(path, "wb") as f:
        head = (
            "ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(verts)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\n"
            f"element face {n}\nproperty list uchar int vertex_indices\nend_header\n"
        )
        f.write(head.encode("ascii"))
        buf = bytearray()
        for v in verts:
            buf += struct.pack("<6f", v[0], v[1], v[2], 0.0, -1.0, 0.0)
        f.write(buf)
        buf = bytearray()
        for i in range(n):
            buf += struct.pack("<B3i", 3, 3 * i, 3 * i + 1, 3 * i + 2)
        f.write(buf)
    # The emitting area, for the radiance that keeps the total power fixed.
    return n * 0.5 * 3.0 * math.sqrt(3.0) / 2.0 * size * size


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int)
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--resolution", type=int, default=128)
    a = ap.parse_args()
    rng = random.Random(a.seed * 1000003 + a.n)
    os.makedirs(a.out, exist_ok=True)
    ply = f"many-{a.n}-emitters.ply"
    area = write_emitters(os.path.join(a.out, ply), a.n, rng)
    radiance = 20.0 / area  # total emitted power ~ 20 pi, whatever N
    spheres = []
    for i in range(12):
        spheres.append((rng.uniform(-3.2, 3.2), rng.uniform(0.3, 0.8), rng.uniform(-3.2, 3.2)))
    r = a.resolution
    with open(os.path.join(a.out, f"many-{a.n}.pbrt"), "w") as f:
        f.write(f"# many-{a.n}: bench/ias/gen_many.py {a.n} (seed {a.seed}): floor, 12 spheres, {a.n} emitting\n")
        f.write("# triangles in a ceiling panel. Direct lighting only.\n")
        f.write('Integrator "path" "integer maxdepth" [ 1 ]\n')
        f.write(f'Film "rgb" "integer xresolution" [ {r} ] "integer yresolution" [ {r} ]\n')
        f.write('PixelFilter "box"\n')
        f.write("LookAt 0 3 9  0 0.6 0  0 1 0\n")
        f.write('Camera "perspective" "float fov" [ 50 ]\n')
        f.write("WorldBegin\n")
        f.write('Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]\n')
        f.write('Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]\n')
        f.write('    "point3 P" [ -6 0 -6  6 0 -6  6 0 6  -6 0 6 ]\n')
        f.write('Material "diffuse" "rgb reflectance" [ 0.3 0.3 0.3 ]\n')
        f.write('Shape "trianglemesh" "integer indices" [ 0 2 1 0 3 2 ]\n')
        f.write('    "point3 P" [ -6 4 -6  6 4 -6  6 4 6  -6 4 6 ]\n')
        for i, (x, rad, z) in enumerate(spheres):
            c = (0.2 + 0.6 * ((i * 37) % 11) / 10.0, 0.5, 0.8 - 0.6 * ((i * 53) % 7) / 6.0)
            f.write("AttributeBegin\n")
            f.write(f"    Translate {x:.4f} {rad:.4f} {z:.4f}\n")
            f.write(f'    Material "diffuse" "rgb reflectance" [ {c[0]:.3f} {c[1]:.3f} {c[2]:.3f} ]\n')
            f.write(f'    Shape "sphere" "float radius" [ {rad:.4f} ]\n')
            f.write("AttributeEnd\n")
        f.write("AttributeBegin\n")
        f.write(f'    AreaLightSource "diffuse" "rgb L" [ {radiance:.6g} {radiance:.6g} {radiance:.6g} ]\n')
        f.write('    Material "diffuse" "rgb reflectance" [ 0 0 0 ]\n')
        f.write(f'    Shape "plymesh" "string filename" [ "{ply}" ]\n')
        f.write("AttributeEnd\n")


if __name__ == "__main__":
    main()
