#!/usr/bin/env python3
"""Scenes the profiles were not tuned on: the given scene's objects under other lights and
cameras, to check `quality` against uniform 4x4 (profiles/quality.toml).

    tools/unseen_scenes.py OUT_DIR [--count N] [--seed S]

Writes OUT_DIR/unseen_K.txt (the objects of scenes/given.txt, 1 to 5 point lights and 0 to
2 spotlights of random colours and places) and OUT_DIR/cameras.txt, one line per scene:
`unseen_K.txt --eye X,Y,Z --look-at X,Y,Z --fov F` (arguments of `octaray render` and
`octaray tradeoff`). The same seed gives the same scenes.
"""

import argparse
import math
import os
import random

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def given_objects():
    """The recursion level and the object block (count and objects) of the given scene."""
    lines = open(os.path.join(ROOT, "scenes", "given.txt")).read().split("\n")
    level = lines[0].strip()
    # the object count is the first non-empty line after the size; the point-light
    # count follows the last object (8 objects of 6 or 7 lines each)
    start = next(i for i in range(2, len(lines)) if lines[i].strip())
    tokens_per = {"sphere": 4, "triangle": 9, "general": 16}
    count = int(lines[start])
    i, blocks = start + 1, []
    for _ in range(count):
        while not lines[i].strip():
            i += 1
        kind = lines[i].strip()
        need = tokens_per[kind] + 3 + 4 + 1
        block, got = [kind], 0
        i += 1
        while got < need:
            toks = lines[i].split()
            got += len(toks)
            if toks:
                block.append(" ".join(toks))
            i += 1
        blocks.append("\n".join(block))
    return level, count, blocks


def f(v):
    return f"{v:.3f}"


def scene(r, level, count, blocks):
    points = []
    for _ in range(r.randint(1, 5)):
        p = (r.uniform(-150, 150), r.uniform(-150, 150), r.uniform(15, 200))
        c = [r.choice([0.0, r.uniform(0.2, 1.0), 1.0]) for _ in range(3)]
        if max(c) == 0:
            c[r.randrange(3)] = 1.0
        points.append(f"{f(p[0])} {f(p[1])} {f(p[2])}\n{f(c[0])} {f(c[1])} {f(c[2])}")
    spots = []
    for _ in range(r.randint(0, 2)):
        p = (r.uniform(-200, 200), r.uniform(-200, 200), r.uniform(60, 250))
        target = (r.uniform(-40, 60), r.uniform(-20, 80), 0.0)
        d = [target[k] - p[k] for k in range(3)]
        c = [r.uniform(0.3, 1.0) for _ in range(3)]
        spots.append(
            f"{f(p[0])} {f(p[1])} {f(p[2])}\n{f(c[0])} {f(c[1])} {f(c[2])}\n"
            f"{f(d[0])} {f(d[1])} {f(d[2])}\n{f(r.uniform(8, 30))}"
        )
    parts = [level, "768", "", str(count)] + blocks + ["", str(len(points))] + points
    parts += ["", str(len(spots))] + spots
    return "\n".join(parts) + "\n"


def camera(r):
    # around the objects (centre near (15, 40, 20)), from low to high
    centre = (15.0, 40.0, 20.0)
    a = r.uniform(0, 2 * math.pi)
    dist = r.uniform(90, 220)
    eye = (centre[0] + dist * math.cos(a), centre[1] + dist * math.sin(a), r.uniform(8, 130))
    look = tuple(centre[k] + r.uniform(-25, 25) for k in range(2)) + (r.uniform(0, 35),)
    fov = r.uniform(45, 90)
    v = lambda p: ",".join(f(x) for x in p)
    return f"--eye {v(eye)} --look-at {v(look)} --fov {fov:.1f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--count", type=int, default=6)
    ap.add_argument("--seed", type=int, default=21)
    a = ap.parse_args()
    os.makedirs(a.out_dir, exist_ok=True)
    r = random.Random(a.seed)
    level, count, blocks = given_objects()
    cams = []
    for k in range(1, a.count + 1):
        name = f"unseen_{k}.txt"
        with open(os.path.join(a.out_dir, name), "w") as out:
            out.write(scene(r, level, count, blocks))
        cams.append(f"{name} {camera(r)}")
    with open(os.path.join(a.out_dir, "cameras.txt"), "w") as out:
        out.write("\n".join(cams) + "\n")
    print("\n".join(cams))


if __name__ == "__main__":
    main()
