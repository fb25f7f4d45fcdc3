#!/usr/bin/env python3
"""streaks.py — how much of an image's error runs along the scanlines (the banding of 1D span
interpolation, bench/contour/RESULTS.md): in every 8x8 block, the RMS of the 8 row means of the
error minus the block mean ("row streaks"), and the same for the 8 column means ("column
streaks"), in 8-bit sRGB levels (mean of the channels). Isotropic noise gives about the same
two numbers; streaks along the rows make the first larger. Pure Python (no numpy).

    bench/contour/streaks.py REFERENCE.pfm IMAGE.pfm...
"""
import array
import sys

K = 8


def read_pfm(path):
    with open(path, "rb") as f:
        if f.readline().strip() != b"PF":
            sys.exit("%s: not an RGB PFM" % path)
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = array.array("f")
        a.frombytes(f.read(w * h * 12))
        if scale > 0:
            a.byteswap()
        return w, h, a


def srgb8(x):
    x = min(max(x, 0.0), 1.0)
    return 255.0 * (12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    w, h, ref = read_pfm(sys.argv[1])
    for path in sys.argv[2:]:
        w2, h2, img = read_pfm(path)
        if (w2, h2) != (w, h):
            sys.exit("%s: not the reference's size" % path)
        e = [sum(srgb8(img[3 * i + c]) - srgb8(ref[3 * i + c]) for c in range(3)) / 3 for i in range(w * h)]
        rows = cols = n = 0.0
        for by in range(0, h - K + 1, K):
            for bx in range(0, w - K + 1, K):
                rm = [sum(e[(by + j) * w + bx + i] for i in range(K)) / K for j in range(K)]
                cm = [sum(e[(by + j) * w + bx + i] for j in range(K)) / K for i in range(K)]
                b = sum(rm) / K
                rows += sum((x - b) ** 2 for x in rm)
                cols += sum((x - b) ** 2 for x in cm)
                n += K
        print("%s: row streaks %.3f, column streaks %.3f" % (path, (rows / n) ** 0.5, (cols / n) ** 0.5))


if __name__ == "__main__":
    main()
