"""Image fuzz (issue 11): mutated JPEG / PNG / WebP / HEIC files through the decoder.

    python bench/bench_fuzz_images.py [--n 5000] [--cli 200] [--seed 11]

Seeds are made here (Pillow and pillow-heif: baseline and progressive JPEG with EXIF, RGB /
palette / 16-bit PNG, WebP, HEIC; 200x150 to 1600x1200), then mutated deterministically:
bit flips, byte overwrites with 00/FF/7F/80, truncation, inserted and deleted runs,
duplicated ranges, splices of two files, width/height fields set to huge values, PNG chunk
lengths and JPEG segment lengths set to huge values, and the issue's 0xFFFFFFFF IDAT.

Every file goes to ``findme_io.imageio.decode_photo`` in a worker process whose file
descriptor 2 is captured per file: the outcome must be a decoded image or an ``ImageError``
(anything else is a crash), nothing may be written on fd 2, and each file must finish
within 5 s (else the worker is killed and restarted: a hang). The worker's peak RSS is
read after every file. A random sample of ``--cli`` files also goes through the real
command line (``findme hypotheses FILE --json``): exit status 0 or 2, and 2 comes with
exactly one stderr line. Reports a table per format, the peak RSS and the slowest files.
"""

from __future__ import annotations

import argparse
import io
import multiprocessing as mp
import os
import random
import resource
import struct
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

TIME_LIMIT_S = 5.0


# ------------------------------------------------------------------------------ seeds
def _picture(w, h, rng):
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([(x * 255 // max(w - 1, 1)), (y * 255 // max(h - 1, 1)),
                    ((x // 16 + y // 16) % 2) * 200], -1).astype(np.uint8)
    img[rng.integers(0, h, 50), rng.integers(0, w, 50)] = 255
    return img


def seeds(rng) -> dict[str, list[bytes]]:
    from PIL import Image
    import pillow_heif  # noqa: F401 - registers HEIF saving
    from findme_io.imageio import _pillow
    _pillow()
    out = defaultdict(list)
    for w, h in ((200, 150), (640, 480), (1024, 768), (1600, 1200)):
        im = Image.fromarray(_picture(w, h, rng))
        ex = Image.Exif()
        ex[0x0112] = int(rng.integers(1, 9))
        ex.get_ifd(0x8769)[0xA405] = 26
        for kw in ({"quality": 90, "exif": ex}, {"quality": 75, "progressive": True}):
            b = io.BytesIO(); im.save(b, "JPEG", **kw); out["jpeg"].append(b.getvalue())
        for mode in ("RGB", "P"):
            b = io.BytesIO(); im.convert(mode).save(b, "PNG"); out["png"].append(b.getvalue())
        b = io.BytesIO(); im.save(b, "WEBP", quality=80); out["webp"].append(b.getvalue())
        if w <= 1024:
            b = io.BytesIO(); im.save(b, "HEIF", quality=70); out["heic"].append(b.getvalue())
    deep = (np.linspace(0, 65535, 320)[None, :].repeat(240, 0)).astype(np.uint16)
    b = io.BytesIO(); Image.fromarray(deep).save(b, "PNG"); out["png"].append(b.getvalue())
    return out


# ------------------------------------------------------------------------------ mutators
def _flip(d, r):
    d = bytearray(d)
    for _ in range(r.randint(1, 20)):
        i = r.randrange(len(d)); d[i] ^= 1 << r.randrange(8)
    return bytes(d)


def _overwrite(d, r):
    d = bytearray(d)
    for _ in range(r.randint(1, 8)):
        i = r.randrange(len(d)); n = r.randint(1, 16)
        d[i:i + n] = bytes([r.choice((0, 0xFF, 0x7F, 0x80))]) * n
    return bytes(d)


def _truncate(d, r):
    return d[:r.randint(1, max(1, len(d) - 1))]


def _insert(d, r):
    i = r.randrange(len(d))
    return d[:i] + os.urandom(r.randint(1, 512)) + d[i:]


def _delete(d, r):
    i = r.randrange(len(d))
    return d[:i] + d[i + r.randint(1, 512):]


def _duplicate(d, r):
    i = r.randrange(len(d)); j = min(len(d), i + r.randint(16, 4096))
    return d[:j] + d[i:j] * r.randint(1, 8) + d[j:]


def _huge_dims(d, r):
    d = bytearray(d)
    big = r.choice((0xFFFF, 0x7FFF, 50000, 65500))
    if d.startswith(b"\x89PNG") and len(d) > 24:
        struct.pack_into(">II", d, 16, r.choice((big, 1 << 30, 0xFFFFFFFF)), big)
    elif d.startswith(b"\xff\xd8"):
        for m in (b"\xff\xc0", b"\xff\xc2"):
            i = d.find(m)
            if i > 0:
                struct.pack_into(">HH", d, i + 5, big, big)
    elif d[4:8] == b"ftyp":
        i = d.find(b"ispe")
        if i > 0:
            struct.pack_into(">II", d, i + 8, big * 16, big * 16)
    else:
        i = d.find(b"VP8")
        if i > 0:
            struct.pack_into("<HH", d, min(i + 14, len(d) - 4), big & 0x3FFF, big & 0x3FFF)
    return bytes(d)


def _huge_length(d, r):
    d = bytearray(d)
    if d.startswith(b"\x89PNG"):
        offs, i = [], 8
        while i + 8 <= len(d):
            offs.append(i)
            i += 12 + struct.unpack_from(">I", d, i)[0]
        if offs:
            struct.pack_into(">I", d, r.choice(offs), r.choice((0xFFFFFFFF, 0x7FFFFFFF, len(d) * 4)))
    elif d.startswith(b"\xff\xd8"):
        i = d.find(b"\xff", r.randrange(2, max(3, len(d) // 8)))
        if 0 < i < len(d) - 4:
            struct.pack_into(">H", d, i + 2, 0xFFFF)
    else:
        i = r.randrange(0, max(1, len(d) - 4))
        struct.pack_into(">I", d, i, 0xFFFFFFF0)
    return bytes(d)


def _idat_bomb(d, r):
    if not d.startswith(b"\x89PNG"):
        return _huge_length(d, r)
    i = d.find(b"IDAT")
    return d[:i - 4] + b"\xff\xff\xff\xff" + d[i:]


MUTATORS = [_flip, _overwrite, _truncate, _insert, _delete, _duplicate, _huge_dims,
            _huge_length, _idat_bomb]


def mutate(d, r, pool):
    if r.random() < 0.05:   # splice two files
        other = r.choice(pool)
        d = d[:r.randrange(1, len(d))] + other[r.randrange(len(other)):]
    for _ in range(r.choice((1, 1, 1, 2, 3))):
        if len(d) < 8:
            break
        d = r.choice(MUTATORS)(d, r)
    return d


# ------------------------------------------------------------------------------ worker
def worker(conn):
    from findme_core.errors import ImageError
    from findme_io.imageio import decode_photo
    err = tempfile.TemporaryFile()
    saved = os.dup(2)
    while True:
        item = conn.recv()
        if item is None:
            break
        name, data = item
        err.seek(0); err.truncate()
        os.dup2(err.fileno(), 2)
        t = time.perf_counter()
        try:
            decode_photo(data, name)
            status, msg = "decoded", ""
        except ImageError as e:
            status, msg = "refused", str(e)
        except BaseException as e:  # noqa: BLE001 - the point: count what escapes
            status, msg = "CRASH", f"{type(e).__name__}: {e}"
        dt = time.perf_counter() - t
        sys.stderr.flush()
        os.dup2(saved, 2)
        err.seek(0)
        leaked = err.read().decode(errors="replace")
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MB
        conn.send((status, msg[:200], dt, leaked[:300], rss))


class Runner:
    def __init__(self):
        self.ctx = mp.get_context("spawn")
        self.start()

    def start(self):
        self.parent, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=worker, args=(child,), daemon=True)
        self.proc.start()

    def run(self, name, data):
        self.parent.send((name, data))
        if self.parent.poll(TIME_LIMIT_S):
            return self.parent.recv()
        self.proc.kill(); self.proc.join()
        rss = 0.0
        self.start()
        return ("HANG", f"over {TIME_LIMIT_S} s", TIME_LIMIT_S, "", rss)

    def close(self):
        self.parent.send(None)
        self.proc.join(10)
        if self.proc.is_alive():
            self.proc.kill()


def cli_check(files, tmp):
    bad = []
    for name, data in files:
        p = os.path.join(tmp, name)
        with open(p, "wb") as f:
            f.write(data)
        r = subprocess.run([sys.executable, "-m", "findme.cli", "hypotheses", p, "--json"],
                           capture_output=True, text=True, timeout=120)
        lines = r.stderr.strip().splitlines()
        ok = (r.returncode == 0 and not lines) or (r.returncode == 2 and len(lines) == 1)
        if not ok or "Traceback" in r.stderr:
            bad.append((name, r.returncode, r.stderr[-300:]))
        os.unlink(p)
    return bad


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=5000, help="mutated files (spread over formats)")
    ap.add_argument("--cli", type=int, default=200, help="of which this many through the CLI")
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args(argv)
    r = random.Random(a.seed)
    base = seeds(np.random.default_rng(a.seed))
    pool = [d for v in base.values() for d in v]
    kinds = list(base)
    files = []
    for i in range(a.n):
        k = kinds[i % len(kinds)]
        files.append((k, f"fuzz_{i:05d}.{k}", mutate(r.choice(base[k]), r, pool)))
    runner = Runner()
    table = defaultdict(Counter)
    times = defaultdict(list)
    crashes, leaks, slow = [], [], []
    peak = 0.0
    t0 = time.perf_counter()
    for k, name, data in files:
        status, msg, dt, leaked, rss = runner.run(name, data)
        table[k][status] += 1
        times[k].append(dt)
        peak = max(peak, rss)
        if status in ("CRASH", "HANG"):
            crashes.append((name, status, msg))
        if leaked:
            leaks.append((name, leaked))
        slow.append((dt, name, status))
    runner.close()
    wall = time.perf_counter() - t0
    print(f"{a.n} mutated files through decode_photo in {wall:.0f} s (seed {a.seed})")
    print(f"{'format':7s} {'files':>6s} {'decoded':>8s} {'refused':>8s} {'crash':>6s} {'hang':>5s} "
          f"{'stderr':>7s}  ms median   p99    max")
    for k in kinds:
        c, t = table[k], np.asarray(times[k]) * 1e3
        nleak = sum(1 for n, _ in leaks if n.endswith("." + k))
        print(f"{k:7s} {sum(c.values()):6d} {c['decoded']:8d} {c['refused']:8d} {c['CRASH']:6d} "
              f"{c['HANG']:5d} {nleak:7d}  {np.median(t):9.1f} {np.percentile(t, 99):6.1f} "
              f"{t.max():6.0f}")
    print(f"peak RSS of the decoding worker: {peak:.0f} MB (limit 1024 MB); "
          f"slowest: " + ", ".join(f"{n} {dt * 1e3:.0f} ms ({s})" for dt, n, s in sorted(slow)[-3:]))
    for name, status, msg in crashes[:10]:
        print(f"  {status} {name}: {msg}")
    for name, text in leaks[:10]:
        print(f"  stderr from {name}: {text!r}")
    bad = []
    if a.cli:
        sample = r.sample([(n, d) for _, n, d in files], min(a.cli, len(files)))
        with tempfile.TemporaryDirectory() as tmp:
            bad = cli_check(sample, tmp)
        print(f"CLI (findme hypotheses FILE --json) on {len(sample)} of them: "
              f"{len(sample) - len(bad)} exited 0 with no stderr or 2 with one line; {len(bad)} did not")
        for name, code, err in bad[:10]:
            print(f"  {name}: exit {code}: {err!r}")
    ok = not crashes and not leaks and not bad and peak < 1024   # the CLI sample counts too
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
