"""Benchmark: `td.animate` of the default 20 s trial (what `simulate --html` adds); prints JSON.

Wall time of the page (kinematics of every frame, Meshcat scene and recording, export), its
size by part, and the load average (the machine is shared). Usage:
    python benchmarks/animate.py [--duration 20] [--out results/bench_animation.html]
"""

import argparse
import base64
import json
import os
import platform
import re
import time

import msgpack

import trunk_drake as td
from trunk_drake.data import models_dir
from trunk_drake.simulation import DEFAULT_GAINS, load_reflex_gains
from trunk_drake.visual.page import embedded_player


def page_parts_mb(html: str) -> dict:
    parts = {"total": len(html)}
    for data in re.findall(r'fetch\("data:application/octet-binary;base64,([^"]+)"\)', html):
        message = msgpack.unpackb(base64.b64decode(data), raw=False, strict_map_key=False)
        kind = "bone meshes" if "/bones/" in message.get("path", "") and message["type"] == "set_object" else message["type"]
        parts[kind] = parts.get(kind, 0) + len(data)
    player = embedded_player(html)
    parts["muscle wrap points"] = len(player["wrap"]["data"])
    parts["activations"] = len(player["activation"]["data"])
    return {k: round(v / 1e6, 2) for k, v in parts.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--out", default="results/bench_animation.html")
    args = parser.parse_args()
    model = td.load_model("sagittal")
    result = td.simulate(model, duration=args.duration, feedforward=td.coactivation(model, 0.02),
                         **load_reflex_gains(models_dir() / DEFAULT_GAINS))
    td.animate(result, args.out, model)  # first call: bone-mesh cache, numba compilation
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    path = td.animate(result, args.out, model)
    wall = time.perf_counter() - t0
    print(json.dumps({
        "machine": platform.processor() or platform.machine(), "python": platform.python_version(),
        "frames": len(result.time), "animate_wall_s": wall, "page_mb": page_parts_mb(path.read_text()),
        "load_average_1min": [load_before[0], os.getloadavg()[0]],
    }, indent=2))


if __name__ == "__main__":
    main()
