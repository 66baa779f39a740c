#!/usr/bin/env python3
"""Image hashes of a fixed corpus, to check that a change leaves every image unchanged.

    tools/image_hashes.py BINARY OUT.txt [--random N] [--size S] [--jobs J]

Renders every scene of scenes/ and N random scenes (seeded: the same N gives the same
scenes) under every built-in profile and a few knob variants, with the default camera and
a random one per scene, and writes one line per image: `scene profile camera md5`.
Compare two binaries' files with `diff`. The random scenes mix spheres, triangles,
quadrics (clipped on no, some or all axes), prisms, point lights, spotlights and mirror
coefficients, at scales from 1e-3 to 1e3.
"""

import argparse
import hashlib
import os
import random
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

VARIANTS = {
    "moller": 'triangle_test = "moller"\n',
    "epsilon": 'ray_offset = "epsilon:1e-3"\n',
    "closest_shadows": "shadow_any_hit = false\n",
    "no_fallback": "single_ray_lanes = 0\n",
    "spp4": "samples_per_pixel = 4\n",
    "spp9_ref": 'path = "reference"\nsamples_per_pixel = 9\n',
}
PROFILES = ["reference", "accurate", "fast", "preview"]


def rnd_color(r):
    return " ".join(f"{r.random():.3f}" for _ in range(3))


def material(r, mirror_bias=0.3):
    ka, kd, ks = (round(r.uniform(0, 0.5), 3) for _ in range(3))
    kr = round(r.uniform(0, 1.0), 3) if r.random() < mirror_bias else round(r.uniform(0, 0.3), 3)
    shine = r.choice([1, 5, 10, 30, 2.5, 0])
    return f"{rnd_color(r)}\n{ka} {kd} {ks} {kr}\n{shine}\n"


def random_scene(seed):
    r = random.Random(seed)
    s = r.choice([1e-3, 0.1, 1.0, 1.0, 1.0, 10.0, 1e3])
    f = lambda v: f"{v * s:.6g}"
    objs = []
    for _ in range(r.randint(1, 9)):
        kind = r.choices(["sphere", "triangle", "general", "prism"], [4, 3, 3, 1])[0]
        c = [r.uniform(-60, 60), r.uniform(-60, 60), r.uniform(0, 40)]
        cx, cy, cz = c
        if kind == "sphere":
            objs.append(f"sphere\n{' '.join(map(f, c))}\n{f(r.uniform(2, 20))}\n" + material(r))
        elif kind == "triangle":
            pts = [[c[i] + r.uniform(-25, 25) for i in range(3)] for _ in range(3)]
            objs.append("triangle\n" + "\n".join(" ".join(map(f, p)) for p in pts) + "\n" + material(r))
        elif kind == "general":
            k = r.choice(["ellipsoid", "cylinder", "cone", "hyperboloid", "paraboloid", "plane", "random"])
            rad = r.uniform(3, 15)
            if k == "ellipsoid":
                a, b, cc = (1 / r.uniform(3, 15) ** 2 for _ in range(3))
                co = [a, b, cc, 0, 0, 0, -2 * a * cx, -2 * b * cy, -2 * cc * cz,
                      a * cx * cx + b * cy * cy + cc * cz * cz - 1]
            elif k == "cylinder":
                co = [1, 1, 0, 0, 0, 0, -2 * cx, -2 * cy, 0, cx * cx + cy * cy - rad * rad]
            elif k == "cone":
                co = [1, 1, -0.3, 0, 0, 0, -2 * cx, -2 * cy, 0.6 * cz, cx * cx + cy * cy - 0.3 * cz * cz]
            elif k == "hyperboloid":
                co = [1, 1, -1, 0, 0, 0, -2 * cx, -2 * cy, 2 * cz, cx * cx + cy * cy - cz * cz - rad]
            elif k == "paraboloid":
                co = [1, 1, 0, 0, 0, 0, -2 * cx, -2 * cy, -rad, cx * cx + cy * cy]
            elif k == "plane":
                co = [0, 0, 0, 0, 0, 0, r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-50, 50)]
            else:
                co = [r.uniform(-1, 1) for _ in range(9)] + [r.uniform(-100, 100)]
            # the quadric in scaled coordinates: degree-2 terms / s², linear / s
            co = [co[i] / s**2 for i in range(6)] + [co[i] / s for i in range(6, 9)] + [co[9]]
            clip = []
            for i in range(3):
                if r.random() < 0.5:
                    clip.append((c[i] - r.uniform(5, 30), r.uniform(5, 60)))
                else:
                    clip.append((0.0, 0.0))
            box = " ".join(f(a) for a, _ in clip) + " " + " ".join(f(b) for _, b in clip)
            objs.append("general\n" + " ".join(f"{v:.6g}" for v in co) + "\n" + box + "\n" + material(r))
        else:
            w = r.uniform(8, 20)
            h = r.uniform(10, 40)
            tri = [[cx, cy], [cx + w, cy + r.uniform(-3, 3)], [cx + w / 2, cy + w * 0.8]]
            base = " ".join(f"{f(p[0])} {f(p[1])} {f(0)}" for p in tri)
            top = " ".join(f"{f(p[0])} {f(p[1])} {f(h)}" for p in tri)
            objs.append(f"prism\n{base}\n{top}\n" + material(r, 0) + f"{r.uniform(0.5, 1):.3f} 1.5 0.0042\n")
    lights = []
    for _ in range(r.randint(0, 3)):
        p = [r.uniform(-100, 100), r.uniform(-100, 100), r.uniform(5, 120)]
        lights.append(" ".join(map(f, p)) + " " + rnd_color(r))
    spots = []
    for _ in range(r.randint(0, 2)):
        p = [r.uniform(-100, 100), r.uniform(-100, 100), r.uniform(20, 150)]
        d = [r.uniform(-1, 1), r.uniform(-1, 1), r.uniform(-1, -0.2)]
        cut = r.choice([5, 20, 45, 90, 120, 180, 0.5])
        spots.append(" ".join(map(f, p)) + " " + rnd_color(r) + " " + " ".join(f"{v:.4f}" for v in d) + f" {cut}")
    level = r.choice([1, 2, 3, 4, 6])
    text = f"{level}\n64\n{len(objs)}\n" + "".join(objs)
    text += f"{len(lights)}\n" + "".join(l + "\n" for l in lights)
    text += f"{len(spots)}\n" + "".join(l + "\n" for l in spots)
    eye = [r.uniform(-150, 150), r.uniform(-150, 150), r.uniform(5, 120)]
    look = [r.uniform(-30, 30), r.uniform(-30, 30), r.uniform(0, 20)]
    cam = ["--eye", ",".join(map(f, eye)), "--look-at", ",".join(map(f, look))]
    default_cam = ["--eye", ",".join(map(f, [100, 100, 50])), "--look-at", ",".join(map(f, [0, 0, 50]))]
    return text, [("default", default_cam), ("random", cam)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("binary")
    ap.add_argument("out")
    ap.add_argument("--random", type=int, default=200)
    ap.add_argument("--size", default="64")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    work = tempfile.mkdtemp(prefix="octaray-hashes-")
    profdir = os.path.join(work, "profiles")
    os.mkdir(profdir)
    profiles = list(PROFILES)
    for name, body in VARIANTS.items():
        path = os.path.join(profdir, f"{name}.toml")
        with open(path, "w") as fh:
            fh.write(body)
        profiles.append(path)
    jobs = []
    scenes_dir = os.path.join(root, "scenes")
    for name in sorted(os.listdir(scenes_dir)):
        if name.endswith(".txt"):
            jobs.append((name, os.path.join(scenes_dir, name), "default", []))
    for i in range(a.random):
        text, cams = random_scene(1000 + i)
        path = os.path.join(work, f"random_{i:04}.txt")
        with open(path, "w") as fh:
            fh.write(text)
        for cam_name, cam in cams:
            jobs.append((f"random_{i:04}", path, cam_name, cam))

    def run(job, profile):
        name, path, cam_name, cam = job
        out = os.path.join(work, f"{abs(hash((name, profile, cam_name)))}.bmp")
        cmd = [a.binary, "render", path, "-o", out, "--size", a.size, "--threads", "1", "--profile", profile] + cam
        p = subprocess.run(cmd, capture_output=True)
        if p.returncode != 0:
            digest = f"exit{p.returncode}"
        else:
            with open(out, "rb") as fh:
                digest = hashlib.md5(fh.read()).hexdigest()
            os.unlink(out)
        pname = os.path.basename(profile).removesuffix(".toml")
        return f"{name} {pname} {cam_name} {digest}"

    tasks = [(j, p) for j in jobs for p in profiles]
    with ThreadPoolExecutor(a.jobs) as ex:
        lines = list(ex.map(lambda t: run(*t), tasks))
    with open(a.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    bad = sum(1 for l in lines if l.split()[-1].startswith("exit"))
    print(f"{len(lines)} images ({bad} failed renders) -> {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
