#!/usr/bin/env bash
# The reproductions of "bounded memory and time on any input", each run under a 4 GiB
# address-space limit (prlimit --as, util-linux) and a 30 s limit (timeout): each must
# end with its exit code (0 or 2), never a signal or 101, within the limits, with its
# message on stderr.
#
#     tools/bounded_inputs.sh [BINARY]      (default: target/release/octaray)
#
# Prints one line per check (PASS/FAIL, exit code, seconds, the check) and exits 1 if
# any failed. Needs bash, prlimit, timeout, truncate, head and yes.
set -u

BIN=$(realpath "${1:-target/release/octaray}")
ROOT=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
LIMIT=4294967296
FAILED=0

# check NAME CODES PATTERN COMMAND [RAW]: COMMAND (a bash command line, where $RUN is
# the binary under the address-space limit) must exit with one of CODES within 30 s,
# its stderr match the extended regular expression PATTERN (empty: anything) and not
# hold the bytes RAW (a printf format).
check() {
    local name=$1 codes=$2 pattern=$3 command=$4 raw=${5:-}
    local start end rc verdict=PASS why=""
    start=$(date +%s.%N)
    # (in a subshell whose own stderr is dropped: it reports a killed child)
    (
        RUN="prlimit --as=$LIMIT $BIN" timeout -s KILL 30 bash -c "$command" >out.txt 2>err.txt
        exit $?
    ) 2>/dev/null
    rc=$?
    end=$(date +%s.%N)
    if [ "$rc" = 137 ]; then
        verdict=FAIL why=" (over 30 s, killed)"
    elif ! [[ " $codes " == *" $rc "* ]]; then
        verdict=FAIL why=" (expected exit $codes)"
    elif [ -n "$pattern" ] && ! grep -Eq -- "$pattern" err.txt; then
        verdict=FAIL why=" (stderr lacks /$pattern/)"
    elif [ -n "$raw" ] && grep -Fq -- "$(printf "$raw")" err.txt; then
        verdict=FAIL why=" (stderr holds raw $raw)"
    fi
    printf '%s  exit %3s  %6.2f s  %s%s\n' "$verdict" "$rc" "$(echo "$end - $start" | bc)" "$name" "$why"
    if [ "$verdict" = FAIL ]; then
        FAILED=1
        sed 's/^/        | /' err.txt | tail -n 4
    fi
}

# 1. a prism under a light of 1e308: photons x power must not overflow into a count
#    of u64::MAX photon jobs
sed 's/^25 25 25$/1e308 1e308 1e308/' "$ROOT/scenes/prism.txt" >bright.txt
check "1. photon count of a 1e308 light" 0 "" \
    '$RUN render bright.txt --size 64 -o bright.bmp'

# 2. the default camera inside a mirror sphere at recursion level 1 000 000: memory
#    must not grow with level x threads (one pixel wide, 64 rows: 6.4e7 mirror rays)
printf '1000000\n8\n1\nsphere\n100 100 50\n10\n1 1 1\n0 0 0 1\n1\n0\n0\n' >mirror.txt
check "2. mirror chain at level 1000000, --threads 16" 0 "" \
    '$RUN render mirror.txt --size 1x64 --threads 16 -o mirror16.bmp'
check "2. mirror chain at level 1000000, --threads 32" 0 "" \
    '$RUN render mirror.txt --size 1x64 --threads 32 -o mirror32.bmp'

# 3. a five-token scene followed by 300 MB that the format ignores (the tokenizer held
#    16 bytes per byte of file)
check "3. 300 MB of ignored text after the scene, from a pipe" 0 "" \
    '{ echo "1 8 0 0 0"; yes "words the format ignores 12 34 56" | head -c 300000000; } | $RUN render /dev/stdin -o tail.bmp'

# 4. a file of 4 GiB + 1 byte: refused from its size, before it is read
truncate -s 4294967297 big.txt
check "4. a 4 GiB + 1 byte file" 2 "big.txt: file: cannot read: 4294967297 bytes: larger than 4 GiB" \
    '$RUN render big.txt -o big.bmp'

# 5. bench-trace on 10 000 identical zero-area triangles (it kept them: 106 s)
{
    printf 'v 0 0 0\nv 1 1 1\nv 2 2 2\n'
    yes 'f 1 2 3' | head -n 10000
} >degenerate.obj
check "5. bench-trace of 10000 zero-area triangles" "0 2" "" \
    '$RUN bench-trace degenerate.obj --reps 1'

# 6. tokens that rewrite a terminal or hide why they were refused, quoted escaped
printf '2\n6\xe2\x80\x8b4\n0 0 0\n' >zwsp.txt
check "6. U+200B inside a number, escaped" 2 "found '6\\\\u\\{200b\\}4'" \
    '$RUN render zwsp.txt -o zwsp.bmp'
printf '1 8 0 0 \x1b[2Jcleared\n' >esc.txt
check "6. an escape sequence in the prose after the scene, escaped in the note" 0 \
    "'\\\\u\\{1b\\}\\[2Jcleared' is not a spotlight count" '$RUN render esc.txt -o esc.bmp' '\033'
printf '1 8 1 \xe2\x80\xaeerehps\n' >bidi.txt
check "6. a bidirectional override in an object kind, escaped" 2 \
    "unknown object kind '\\\\u\\{202e\\}erehps'" '$RUN render bidi.txt -o bidi.bmp' '\342\200\256'
check "6. a zero-width space, never raw" 2 "" '$RUN render zwsp.txt -o zwsp.bmp' '\342\200\213'

# 7. an OBJ file with lone-CR line ends and a bad face index (read as one line: the
#    bad index went unnoticed and the mesh rendered empty)
printf 'v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 9\r' >cr.obj
printf '1 8 1 mesh cr.obj 1 1 1 0.4 0.2 0.2 0 1 1 0 0 100 1 1 1 0\n' >cr.txt
check "7. OBJ with lone-CR lines and a bad face index" 2 "cr.obj:4: f: vertex index 9 out of range" \
    '$RUN render cr.txt -o cr.bmp'

# messages: no fake position, `-` is standard input, profile errors in plain words,
# an object beyond f32's range named
check "an unreadable file has no position" 2 "nope.txt: file: cannot read: " \
    '$RUN render nope.txt -o nope.bmp'
check "- reads the scene from standard input" 0 "" \
    'echo "1 8 0 0 0" | $RUN render - -o dash.bmp'
printf 'photons = 18446744073709551616\n' >big.toml
check "a profile value out of range, in plain words" 2 "big.toml:1:11: key .photons.: expected an integer from 0 to 10000000, found 18446744073709551616" \
    '$RUN render --profile ./big.toml -o p.bmp'
printf "photons = 1\n'photons' = 2\n" >twice.toml
check "a profile key set twice" 2 "twice.toml:2:1: key .photons.: set twice" \
    '$RUN render --profile ./twice.toml -o p.bmp'
printf '3\n64\n1\nsphere\n100 100 50\n2e19\n1 0 0\n0.4 0.2 0.2 0.2\n10\n1\n70 70 70 1 1 1\n0\n' >huge.txt
check "a sphere of radius 2e19 around the camera is named" 0 "sphere 1 reaches farther from the camera than f32's range" \
    '$RUN render huge.txt --size 16 -o huge.bmp'

exit $FAILED
