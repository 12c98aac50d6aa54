#!/usr/bin/env python3
"""Hostile-input sweep of the rig path: makes N damaged copies of a GLB and runs bodyfit-fit on each.

Usage: tools/mutate_glb.py BODYFIT_FIT RIG.glb [N] [OUT_DIR]

Copy k (k = 1..N, seeded by k, so the sweep is the same on every machine) is, by k mod 4: the file cut at a random
length; up to 20 random bytes anywhere; up to 8 bytes of the JSON chunk replaced by JSON punctuation or digits; up to
200 random bytes in the binary chunk. Every run must end with exit 0 (a fit) or exit 2 and a one-line
"bodyfit-fit: error: ..." (or a parse error naming the file); anything else (a signal, another code, a hang past
120 s) is listed and makes the script exit 1. Prints the counts and the distinct error messages (numbers replaced by N, parentheses by (...)).
"""
import collections
import os
import random
import re
import subprocess
import sys


def mutate(src: bytes, k: int) -> bytes:
    r = random.Random(k)
    b = bytearray(src)
    json_length = int.from_bytes(b[12:16], "little")
    mode = k % 4
    if mode == 0:
        return bytes(b[: r.randrange(len(b))])
    if mode == 1:
        for _ in range(r.randrange(1, 20)):
            b[r.randrange(len(b))] = r.randrange(256)
    elif mode == 2:
        for _ in range(r.randrange(1, 8)):
            b[20 + r.randrange(json_length)] = r.choice(b'0123456789-.e,:{}[]"')
    else:
        start = 20 + json_length + 8
        for _ in range(r.randrange(1, 200)):
            b[start + r.randrange(len(b) - start)] = r.randrange(256)
    return bytes(b)


def main() -> int:
    if len(sys.argv) < 3:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    fit, rig = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 60
    out = sys.argv[4] if len(sys.argv) > 4 else "out/mutate_glb"
    os.makedirs(out, exist_ok=True)
    src = open(rig, "rb").read()
    codes = collections.Counter()
    messages = collections.Counter()
    bad = []
    for k in range(1, n + 1):
        path = os.path.join(out, "m%d.glb" % k)
        with open(path, "wb") as f:
            f.write(mutate(src, k))
        try:
            p = subprocess.run([fit, path, "-o", os.path.join(out, "m%d.json" % k)], capture_output=True, text=True,
                               errors="replace", timeout=120)
            code = p.returncode
        except subprocess.TimeoutExpired:
            code = "timeout"
        codes[code] += 1
        if code == 2:
            last = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
            messages[re.sub(r"[0-9]+", "N", re.sub(r"\([^)]*\)", "(...)", last.replace(path, "FILE").split(" at line")[0]))[:110]] += 1
        elif code != 0:
            bad.append((k, code))
    print("exit codes:", dict(codes))
    for message, count in messages.most_common():
        print("%4d  %s" % (count, message))
    for k, code in bad:
        print("FAILED: copy %d ended with %s" % (k, code))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
