#!/usr/bin/env python3
"""The figures a farm user plans with (benches/README.md, "Farm: per-tile overhead and
frames per hour"), from whole processes:

  1. per-tile overhead at 4K, 4x4 supersampled, for 4, 16 and 64 tiles of the given and
     the prism scene: each tile's whole-process time (fork to exit) against what the
     process itself reports rendering and writing; the rest (process start, scene parse,
     BVH build, photon map, digest, exit) is the per-tile overhead; and the same frame
     cut into 16 contiguous bands of rows (--crop), against the 16 interleaved tiles;
  2. frames per hour of a 4K flythrough: a camera path of FRAMES frames rendered by one
     process, each frame prepared in the f32 frame its eye picks (frames that pick the
     same one share a preparation: `prepared with frame K`, counted as 0 s here).

    benches/farm.py [--bin target/release/octaray] [--threads 2] [--frames 4] [--size 3840x2160]

Prints markdown tables. Each assembled frame is checked against the whole one (cmp).
"""

import argparse
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINE = re.compile(r"\((?:prepare ([0-9.]+) s|prepared with frame \d+), render ([0-9.]+) s; write ([0-9.]+) s\), "
                  r"([0-9.]+) M rays")


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def run(bin, args):
    """One `octaray render` process: its wall time from fork to exit, and (prepare,
    render, write, M rays) of each frame it reported."""
    start = time.perf_counter()
    out = subprocess.run([bin, "render"] + args, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if out.returncode != 0:
        sys.exit(f"octaray {' '.join(args)} failed: {out.stderr}")
    frames = [tuple(float(g or 0) for g in m.groups()) for m in map(LINE.search, out.stderr.splitlines()) if m]
    return wall, frames


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target/release/octaray"))
    ap.add_argument("--threads", default="2")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", default="3840x2160")
    a = ap.parse_args()
    w, h = map(int, a.size.split("x"))
    work = tempfile.mkdtemp(prefix="octaray-farm-figures.")
    ss16 = os.path.join(work, "ss16.toml")
    with open(ss16, "w") as f:
        f.write("samples_per_pixel = 16\n")
    print(f"load before: {load()}; {os.cpu_count()} CPUs; octaray --threads {a.threads}; {a.size}, 4x4 supersampled\n")
    print("| scene | pieces | whole-process time: whole frame / sum of pieces | mean piece | slowest piece | rays: least–most per piece | overhead per piece (of it photon map) | **overhead / mean piece** |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in ["given", "prism"]:
        base = [os.path.join(ROOT, "scenes", scene + ".txt"), "--size", a.size,
                "--profile", ss16, "--threads", a.threads]
        whole_png = os.path.join(work, "whole.png")
        whole, _ = run(a.bin, base + ["-o", whole_png])
        splits = [("tiles", n) for n in (4, 16, 64)] + ([("bands", 16)] if scene == "given" else [])
        for kind, n in splits:
            walls, overhead, photons, rays, names = [], [], [], [], []
            for i in range(n):
                name = os.path.join(work, f"t_{i}.png")
                if kind == "tiles":
                    piece = ["--tile", f"{i}/{n}"]
                else:
                    piece = ["--crop", f"0,{w},{i * h // n},{(i + 1) * h // n}"]
                wall, [(prep, render, write, mrays)] = run(a.bin, base + piece + ["-o", name])
                walls.append(wall)
                overhead.append(wall - render - write)
                photons.append(prep)
                rays.append(mrays)
                names.append(name)
            asm = os.path.join(work, "a.png")
            subprocess.run([a.bin, "assemble", *names, "-o", asm], check=True, capture_output=True)
            if open(asm, "rb").read() != open(whole_png, "rb").read():
                sys.exit(f"{scene}: {n} {kind} assembled differ from the whole frame")
            for name in names + [asm]:
                os.remove(name)
            mean = statistics.mean(walls)
            o = statistics.mean(overhead)
            print(f"| {scene} | {n} {kind} | {whole:.2f} s / {sum(walls):.2f} s | {mean:.3f} s "
                  f"| {max(walls):.3f} s ({max(walls) / mean:.2f}× mean) | {min(rays):.2f}–{max(rays):.2f} M "
                  f"| {o * 1e3:.0f} ms ({statistics.mean(photons) * 1e3:.0f} ms) | **{100 * o / mean:.2f} %** |")
    print(f"\nload between: {load()}\n")

    # a flythrough: the viewer benchmark's orbit (radius 141, 3 degrees a frame, bobbing)
    flight = os.path.join(work, "flight.txt")
    with open(flight, "w") as f:
        for k in range(a.frames):
            t = math.radians(45 + 3 * k)
            f.write(f"{141.42 * math.cos(t):.4f} {141.42 * math.sin(t):.4f} "
                    f"{50 + 20 * math.sin(2 * t):.4f}  0 0 10  0 0 1  80\n")
    print("| flythrough, one process | frames | whole process | per frame | of it: prepare / render / write | **frames per hour** |")
    print("|---|---|---|---|---|---|")
    for scene in ["given", "prism"]:
        os.makedirs(os.path.join(work, scene), exist_ok=True)
        wall, frames = run(a.bin, [os.path.join(ROOT, "scenes", scene + ".txt"), "--size", a.size,
                                   "--profile", ss16, "--threads", a.threads,
                                   "--camera-path", flight, "-o", os.path.join(work, scene, "f_%04d.png")])
        n = len(frames)
        prep, render, write = (statistics.mean(f[k] for f in frames) for k in range(3))
        print(f"| {scene} | {n} | {wall:.2f} s | {wall / n:.2f} s | {prep:.3f} / {render:.2f} / {write:.2f} s "
              f"| **{3600 * n / wall:.0f}** |")
    print(f"\nload after: {load()}")
    subprocess.run(["rm", "-rf", work])


if __name__ == "__main__":
    main()
