"""What the reflection path's second opinion (the confidence's guided selection) costs.

    python scripts/bench_second_opinion.py

Median end-to-end ``detect_symmetries`` time on every 7th SCAPE mesh (10 meshes), with and without
``ReflectionConfig(second_opinion=...)``; spectrum included.
"""
import time
import warnings

import numpy as np

warnings.filterwarnings("ignore")
from symtorch.eval.benchmarks import list_benchmark, load_mesh
from symtorch.detect import detect_symmetries, DetectConfig
from symtorch.detect.config import ReflectionConfig
meshes = list_benchmark("SCAPE")[::7][:10]
for so in (True, False):
    ts = []
    for m in meshes:
        v, f = load_mesh(m[1])
        t = time.perf_counter()
        cfg = DetectConfig(reflection=ReflectionConfig(second_opinion=so))
        detect_symmetries(v, f, config=cfg)
        ts.append(time.perf_counter() - t)
    print("second_opinion", so, "median", round(float(np.median(ts)), 3), "s")
