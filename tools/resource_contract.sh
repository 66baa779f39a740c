#!/usr/bin/env bash
# Measures the memory of the resource contract in README.md ("Limits and resources"):
# writes each input at or near its limit and runs `octaray render` on it under
# /usr/bin/time -v, printing the whole process's maximum resident set size and time.
#
#     tools/resource_contract.sh [BINARY]      (default: target/release/octaray)
#
# Needs bash, python3 and GNU time (/usr/bin/time). Takes a few minutes on two cores
# (the 10 million photons alone about a minute) and about 1 GB of disk in a
# temporary directory.
set -eu

BIN=$(realpath "${1:-target/release/octaray}")
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cd "$WORK"

# measure WHAT ARGS...: one line: max RSS, wall time, exit code, what
measure() {
    local what=$1
    shift
    local rc=0
    /usr/bin/time -v "$BIN" "$@" >out.txt 2>err.txt || rc=$?
    local rss wall
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' err.txt)
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' err.txt)
    printf '%10.1f MB  %8s  exit %s  %s\n' "$(echo "$rss / 1000" | bc -l)" "$wall" "$rc" "$what"
    rm -f ./*.bmp ./*.png
}

python3 - <<'EOF'
import math, random
# spheres: 100 000 and 1 000 000 (one line each)
for n, name in [(100_000, "spheres100k.txt"), (1_000_000, "spheres1m.txt")]:
    r = random.Random(1)
    with open(name, "w") as f:
        f.write(f"2\n64\n{n}\n")
        for _ in range(n):
            f.write("sphere %.3f %.3f %.3f %.3f 1 0 0 0.4 0.2 0.2 0.2 10\n" % (
                r.uniform(-400, 400), r.uniform(-400, 400), r.uniform(0, 100), r.uniform(0.1, 2)))
        f.write("1\n70 70 70 1 1 1\n0\n")
# a triangle mesh: a height field of 1 000 000 triangles
nx, ny = 1000, 500
with open("grid1m.obj", "w") as f:
    for j in range(ny + 1):
        for i in range(nx + 1):
            f.write("v %.4f %.4f %.4f\n" % (-200 + 400 * i / nx, -200 + 400 * j / ny,
                                           10 + 5 * math.sin(i * 0.1) * math.cos(j * 0.1)))
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i + 1
            f.write("f %d %d %d\nf %d %d %d\n" % (a, a + 1, a + nx + 2, a, a + nx + 2, a + nx + 1))
with open("mesh1m.txt", "w") as f:
    f.write("2 64 1 mesh grid1m.obj 1 0 0 0.4 0.2 0.2 0.2 10 1 70 70 70 1 1 1 0\n")
# lights: 1 000 000 point lights over the given scene's objects
with open("lights1m.txt", "w") as f:
    f.write("1\n64\n1\nsphere 0 0 10 5 1 0 0 0.4 0.2 0.2 0.2 10\n1000000\n")
    r = random.Random(2)
    for _ in range(1_000_000):
        f.write("%.2f %.2f %.2f 1e-6 1e-6 1e-6\n" % (r.uniform(-400, 400), r.uniform(-400, 400), r.uniform(50, 200)))
    f.write("0\n")
EOF
printf '1 16384 0 1 70 70 70 1 1 1 0\n' >empty.txt
printf 'photons = 1000000\n' >photons1m.toml
printf 'photons = 10000000\n' >photons10m.toml
printf '1000000\n8\n1\nsphere\n100 100 50\n10\n1 1 1\n0 0 0 1\n1\n0\n0\n' >mirror.txt

measure "the given scene, 768 x 768 (baseline)" render -o given.bmp
measure "image 4096 x 4096, BMP (an empty scene)" render empty.txt --size 4096 -o i.bmp
measure "image 16384 x 16384, BMP (the largest)" render empty.txt -o i.bmp
measure "image 8192 x 8192, PNG" render empty.txt --size 8192 -o i.png
measure "recursion level 1000000, mirror sphere, 1 x 64, --threads 2" \
    render mirror.txt --size 1x64 --threads 2 -o m.bmp
measure "100 000 spheres, 64 x 64" render spheres100k.txt --size 64 -o s.bmp
measure "1 000 000 spheres, 64 x 64" render spheres1m.txt --size 64 -o s.bmp
measure "1 000 000 mesh triangles (a 36 MB OBJ), 64 x 64" render mesh1m.txt --size 64 -o s.bmp
measure "1 000 000 point lights, 8 x 8" render lights1m.txt --size 8 -o s.bmp
measure "1 000 000 photons (scenes/prism.txt), 64 x 64" \
    render "$ROOT/scenes/prism.txt" --size 64 --profile ./photons1m.toml -o p.bmp
measure "10 000 000 photons (the largest), 64 x 64" \
    render "$ROOT/scenes/prism.txt" --size 64 --profile ./photons10m.toml -o p.bmp
{ echo "1 8 0 0 0"; yes "words the format ignores 12 34 56" | head -c 300000000; } >tail.txt
measure "a five-token scene + 300 MB the format ignores" render tail.txt -o t.bmp
rm -f tail.txt
