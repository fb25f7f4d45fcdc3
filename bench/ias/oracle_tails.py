#!/usr/bin/env python3
"""oracle_tails.py — how much of an image's relMSE sits in its worst pixels (stop 20's oracles).

    bench/ias/oracle_tails.py PENUMBRA CONVERGED.exr BLACK.exr IMAGE.exr [IMAGE.exr ...]

BLACK.exr is an all-zero image of the same size (any render of an unlit scene with the same
resolution and crop window); with it `penumbra diff --error-image` writes the converged render
itself as PFM (|image - reference| x 16), which pure Python reads. Per image: relMSE (as `penumbra
diff`: mean over pixels and channels of (a - b)^2 / (b^2 + 0.01)), the shares of it in the worst 16
pixels, worst 1% and worst 10%, and the relMSE without the worst 1% of pixels.
"""
import os
import struct
import subprocess
import sys
import tempfile


def read_pfm(path):
    with open(path, "rb") as f:
        f.readline()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = struct.unpack(("<" if scale < 0 else ">") + f"{w * h * 3}f", f.read(12 * w * h))
    return [x / 16.0 for x in data]


def diff_image(penumbra, ref, img, out):
    subprocess.run([penumbra, "diff", ref, img, "--error-image", out], check=True, capture_output=True)
    return read_pfm(out)


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    penumbra, conv, black = sys.argv[1:4]
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "e.pfm")
        ref = diff_image(penumbra, black, conv, out)
        n = len(ref) // 3
        for img in sys.argv[4:]:
            e = diff_image(penumbra, conv, img, out)
            t = sorted((sum(e[3 * i + c] ** 2 / (ref[3 * i + c] ** 2 + 0.01) for c in range(3)) / 3 for i in range(n)),
                       reverse=True)
            tot = sum(t)
            k1 = max(1, n // 100)
            print(f"{os.path.basename(img)}: relMSE {tot / n:.5f}, worst 16 px {sum(t[:16]) / tot:.2f}, "
                  f"worst 1% {sum(t[:k1]) / tot:.2f}, worst 10% {sum(t[:n // 10]) / tot:.2f}, "
                  f"without the worst 1% {sum(t[k1:]) / n:.5f}")


if __name__ == "__main__":
    main()
