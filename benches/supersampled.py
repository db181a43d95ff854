"""Error of renders against one drawn at FACTOR × FACTOR the pixels and box-averaged down.

    pip install pillow numpy
    python3 benches/supersampled.py FACTOR LARGE.png TEST.png...

All images are 8-bit sRGB PNGs; the comparison is in linear RGB. LARGE must be exactly FACTOR
times each TEST's width and height. Prints, per TEST, its RMSE against the averaged image and
its mean difference (negative: darker).
"""

import sys

import numpy as np
from PIL import Image


def linear(path):
    srgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


factor, large, tests = int(sys.argv[1]), linear(sys.argv[2]), sys.argv[3:]
height, width = large.shape[0] // factor, large.shape[1] // factor
truth = large.reshape(height, factor, width, factor, 3).mean(axis=(1, 3))
for path in tests:
    difference = linear(path) - truth
    rmse = np.sqrt((difference**2).mean())
    print(f"{path}: RMSE {rmse:.4f}, mean difference {difference.mean():+.4f}")
