#!/usr/bin/env python3
"""error_map.py — where an image's relMSE lives, against a converged render (both PFM, RGB).

    bench/ias/error_map.py CONVERGED.pfm IMAGE.pfm [IMAGE.pfm ...]

Per image: the relMSE (mean over pixels and channels of (a - b)^2 / (b^2 + 0.01), as `penumbra
diff`), the share of it in the worst 16 pixels, the worst 1% and the worst 10%, and the share per
bin of the converged pixel's luminance. Pure Python (no numpy), for 128x128 crops.
"""
import struct
import sys

EPS = 0.01
BINS = (0.02, 0.1, 0.3, 1.0, 3.0, float("inf"))


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        channels = 3 if kind == b"PF" else 1
        n = width * height * channels
        data = struct.unpack(("<" if scale < 0 else ">") + f"{n}f", f.read(4 * n))
    if channels != 3:
        sys.exit(f"{path}: an RGB PFM is needed")
    return width, height, data


def luminance(d, i):
    return 0.2126 * d[3 * i] + 0.7152 * d[3 * i + 1] + 0.0722 * d[3 * i + 2]


def report(conv, path):
    w, h, ref = conv
    w2, h2, img = read_pfm(path)
    if (w2, h2) != (w, h):
        sys.exit(f"{path}: {w2}x{h2}, the converged render is {w}x{h}")
    n = w * h
    terms = []
    for i in range(n):
        e = sum((img[3 * i + c] - ref[3 * i + c]) ** 2 / (ref[3 * i + c] ** 2 + EPS) for c in range(3)) / 3
        terms.append((e, luminance(ref, i)))
    total = sum(e for e, _ in terms)
    worst = sorted((e for e, _ in terms), reverse=True)

    def share(k):
        return sum(worst[:k]) / total if total > 0 else 0.0

    per_bin = [0.0] * len(BINS)
    count = [0] * len(BINS)
    for e, lum in terms:
        b = next(k for k, top in enumerate(BINS) if lum < top)
        per_bin[b] += e
        count[b] += 1
    bins = " ".join(f"<{top:g}: {count[b]} px {per_bin[b] / total:.2f}" for b, top in enumerate(BINS))
    print(f"{path}: relMSE {total / n:.5f}; worst 16 px {share(16):.2f}, 1% {share(n // 100):.2f}, "
          f"10% {share(n // 10):.2f}; by converged luminance {bins}")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    conv = read_pfm(sys.argv[1])
    for path in sys.argv[2:]:
        report(conv, path)


if __name__ == "__main__":
    main()
