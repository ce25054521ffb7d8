#!/usr/bin/env python3
"""frame_compare: one walk's frames at several --pixel-error values against the exact frames.

    python3 tests/bench/frame_compare.py --exact DIR --run T=DIR [--run T=DIR ...]
                                         [--label NAME] [--from 2] [--cap 99]
                                         [--tsv OUT.tsv] [--markdown OUT.md] [--json OUT.jsonl]
                                         [--pair T:FRAME:OUT.png] [--supersampled DIR]

Every DIR is what tests/bench/pixel_error_curve.sh leaves for one run of frontier-view:
DIR/report.jsonl (--report), DIR/png/frame_NNNNN.png (--png-dir, --png-every 1) and
DIR/ids/frame_NNNNN.ids (--ids-dir). --exact is the reference run (T = 0, --sync-paging).

Per run, over the frames from --from on (the issue's targets say "from the third frame on",
frame indices start at 0), frame by frame against the exact frame of the same index:
  psnr      RGB PSNR of the PNGs (MSE over all channels); a frame identical to the exact one
            counts as --cap dB (PSNR is infinite there), so the mean stays finite;
  ids       share of all pixels whose first-hit id equals the exact frame's (background included);
  coverage  share of the exact frame's geometry pixels (id != 0xFFFFFFFF) where the run's frame
            has a first hit (an unconfirmed pixel of a pegged frame has no id: it counts as none);
  image coverage  the same share, counting the run's PNG pixels whose colour is not the
            background colour (the commonest colour of the exact frame's background pixels;
            black when it has none): pixels reconstructed from a few samples count here;
            black frames: frames whose image coverage is below 1 %;
  overdraw  pixels with geometry where the exact frame has background, and their distance in
            pixels to the nearest exact geometry pixel (an exact Euclidean distance transform,
            Felzenszwalb & Huttenlocher 2012): how far a proxy's silhouette reaches out of the
            exact one, to set against --pixel-error, the bound the store's proxies are chosen by;
  proxy ids differing ids among geometry pixels over the frame's proxy_pixels (report.jsonl):
            the share of proxy pixels naming another primitive than the exact frame, on the
            assumption that pixels of resident pages name the exact primitive (an upper bound
            when they do not; capped at 1).
  psnr 4spp (with --supersampled DIR: the exact walk at twice the width and height, e.g. the
            1280x720 exact frames for a 640x360 walk) RGB PSNR against those frames, each 2x2
            block averaged: four samples a pixel, closer to what the model looks like than one.
            Where triangles are far below a pixel the one-sample exact frame is aliasing noise
            (its own PSNR against the 4-spp frame says how much); a proxy, smoother, is judged
            here on what it should show.
Whole run (all frames, from report.jsonl): p50/p95 frame ms, total bytes read, max resident MiB,
peak RSS MiB (the process's, from the summary), the most frames' `parked` (jobs or pixels that
waited for a page: a pegged cut never parks), and the first frame (from frame 0) with coverage >= 99 % and the walk time until it ends (the
sum of frame_ms of frames 0..k; the store's opening is not in it).
--pair T:FRAME:OUT.png writes run T's frame FRAME beside the exact frame of that index (left: the
run, right: exact, 8 grey pixels between): what a user sees against what it should be.
Exit codes: 0 ok, 1 bad input (missing or malformed files, named), 2 bad options.
Pure Python (zlib only; no numpy or PIL needed).
"""
import argparse
import array
import itertools
import json
import math
import operator
import os
import struct
import sys
import zlib

BACKGROUND = 0xFFFFFFFF


class BadInput(Exception):
    pass


def read_png(path):
    """(width, height, RGB bytes) of an 8-bit RGB or RGBA, non-interlaced PNG (what libpng writes
    for frontier-view), every PNG row filter undone."""
    try:
        data = open(path, "rb").read()
    except OSError as e:
        raise BadInput(f"{path}: {e.strerror}")
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise BadInput(f"{path}: not a PNG file (offset 0)")
    pos, idat, header = 8, [], None
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if pos + 12 + n > len(data):
            raise BadInput(f"{path}: chunk {kind!r} at offset {pos} runs past the end of the file")
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body[:13])
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + n
    if header is None:
        raise BadInput(f"{path}: no IHDR chunk")
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace != 0:
        raise BadInput(f"{path}: only 8-bit RGB/RGBA non-interlaced PNGs are read (bit depth {depth}, "
                       f"colour type {colour}, interlace {interlace})")
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as e:
        raise BadInput(f"{path}: IDAT does not inflate: {e}")
    bpp = 3 if colour == 2 else 4
    stride = width * bpp
    if len(raw) != height * (stride + 1):
        raise BadInput(f"{path}: {len(raw)} bytes of image data, expected {height * (stride + 1)}")
    out = bytearray(height * stride)
    prev = bytearray(stride)
    mask = itertools.repeat(255)
    for y in range(height):
        start = y * (stride + 1)
        kind = raw[start]
        line = bytearray(raw[start + 1:start + 1 + stride])
        if kind == 0:
            pass
        elif kind == 1:  # Sub: a running sum per channel
            for c in range(bpp):
                line[c::bpp] = bytes(map(operator.and_, itertools.accumulate(line[c::bpp]), mask))
        elif kind == 2:  # Up
            line = bytearray(map(operator.and_, map(operator.add, line, prev), mask))
        elif kind == 3:  # Average
            for x in range(stride):
                a = line[x - bpp] if x >= bpp else 0
                line[x] = (line[x] + ((a + prev[x]) >> 1)) & 255
        elif kind == 4:  # Paeth
            for x in range(stride):
                b = prev[x]
                if x >= bpp:
                    a = line[x - bpp]
                    c = prev[x - bpp]
                    pa = abs(b - c)
                    pb = abs(a - c)
                    pc = abs(a + b - 2 * c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                else:
                    pred = b
                line[x] = (line[x] + pred) & 255
        else:
            raise BadInput(f"{path}: row {y} has filter type {kind} (offset {start} of the inflated data)")
        out[y * stride:(y + 1) * stride] = line
        prev = line
    if bpp == 4:
        rgb = bytearray(width * height * 3)
        for c in range(3):
            rgb[c::3] = out[c::4]
        out = rgb
    return width, height, bytes(out)


def write_png(path, width, height, rgb):
    """An 8-bit RGB PNG of `rgb` (rows top to bottom), every row unfiltered."""
    stride = 3 * width
    raw = b"".join(b"\x00" + rgb[y * stride:(y + 1) * stride] for y in range(height))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    try:
        with open(path, "wb") as f:
            f.write(data)
    except OSError as e:
        raise BadInput(f"{path}: {e.strerror}")


def write_pair(path, left, right, gap=8):
    """left and right, (width, height, rgb) of one size, side by side with a grey gap."""
    (w, h, a), (w2, h2, b) = left, right
    if (w, h) != (w2, h2):
        raise BadInput(f"{path}: frames of {w}x{h} and {w2}x{h2} cannot be paired")
    grey = b"\x80" * (3 * gap)
    rows = [a[y * 3 * w:(y + 1) * 3 * w] + grey + b[y * 3 * w:(y + 1) * 3 * w] for y in range(h)]
    write_png(path, 2 * w + gap, h, b"".join(rows))


def read_ids(path, pixels):
    try:
        data = open(path, "rb").read()
    except OSError as e:
        raise BadInput(f"{path}: {e.strerror}")
    if len(data) != 4 * pixels:
        raise BadInput(f"{path}: {len(data)} bytes, expected {4 * pixels} (uint32 per pixel)")
    ids = array.array("I")
    ids.frombytes(data)
    if sys.byteorder != "little":
        ids.byteswap()
    return ids


def read_report(path):
    frames, summary = [], None
    try:
        lines = open(path).read().splitlines()
    except OSError as e:
        raise BadInput(f"{path}: {e.strerror}")
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            j = json.loads(line)
        except json.JSONDecodeError as e:
            raise BadInput(f"{path}:{number}: not JSON: {e}")
        if "summary" in j:
            summary = j["summary"]
        else:
            frames.append(j)
    if summary is None:
        raise BadInput(f"{path}: no summary line (did the walk finish?)")
    return frames, summary


# Squared differences of two bytes, indexed by a - b in -255..255 (negative indices wrap).
SQUARE = [d * d for d in range(256)] + [(511 - p) ** 2 for p in range(256, 511)]


def psnr(a, b, cap):
    if a == b:
        return cap
    sse = sum(map(SQUARE.__getitem__, map(operator.sub, a, b)))
    mse = sse / len(a)
    return min(cap, 10.0 * math.log10(255.0 * 255.0 / mse))


def box_down2(w, h, rgb):
    """The (w/2) x (h/2) image of 2x2 block means of `rgb` (w x h, RGB bytes), as floats."""
    W, H = w // 2, h // 2
    out = array.array("d", bytes(8 * W * H * 3))
    row = 3 * w
    for y in range(H):
        top = rgb[2 * y * row:(2 * y + 1) * row]
        bottom = rgb[(2 * y + 1) * row:(2 * y + 2) * row]
        # Pairs of horizontal neighbours, per channel: columns 2x and 2x + 1.
        sums = list(map(operator.add, map(operator.add, top, bottom), itertools.repeat(0)))
        o = y * W * 3
        for c in range(3):
            even, odd = sums[c::6][:W], sums[3 + c::6][:W]
            out[o + c:o + 3 * W:3] = array.array("d", (0.25 * (a + b) for a, b in zip(even, odd)))
    return out


def psnr_float(reference, rgb, cap):
    sse = sum(d * d for d in map(operator.sub, reference, rgb))
    if sse == 0:
        return cap
    return min(cap, 10.0 * math.log10(255.0 * 255.0 * len(rgb) / sse))


def _envelope_1d(f, n):
    """Felzenszwalb & Huttenlocher's 1-D squared distance transform of f (length n)."""
    INF = float("inf")
    d = [0.0] * n
    v = [0] * n
    z = [0.0] * (n + 1)
    k = 0
    start = next((q for q in range(n) if f[q] < INF), None)
    if start is None:
        return [INF] * n
    v[0] = start
    z[0], z[1] = -INF, INF
    for q in range(start + 1, n):
        fq = f[q]
        if fq == INF:
            continue
        while True:
            r = v[k]
            s = ((fq + q * q) - (f[r] + r * r)) / (2 * (q - r))
            if s <= z[k]:
                k -= 1
                continue
            break
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = INF
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        r = v[k]
        d[q] = (q - r) * (q - r) + f[r]
    return d


def distance_to_geometry(exact, width, height):
    """Per pixel, the Euclidean distance (pixels) to the nearest pixel where `exact` has geometry
    (exact 2-D transform: columns, then rows; inf when the frame has no geometry)."""
    INF = float("inf")
    columns = []
    for x in range(width):
        f = [0.0 if exact[y * width + x] != BACKGROUND else INF for y in range(height)]
        columns.append(_envelope_1d(f, height))
    out = [0.0] * (width * height)
    for y in range(height):
        row = _envelope_1d([columns[x][y] for x in range(width)], width)
        out[y * width:(y + 1) * width] = [math.sqrt(v) for v in row]
    return out


def overdraw_distances(exact, run, width, height, distance):
    """Distances (pixels) from every pixel where `run` has geometry and `exact` has none to the
    nearest exact geometry pixel; `distance()` gives the exact frame's transform (computed once)."""
    over = [p for p in range(width * height) if run[p] != BACKGROUND and exact[p] == BACKGROUND]
    if not over:
        return []
    field = distance()
    return [field[p] for p in over]


def background_colour(rgb, ids):
    """The commonest colour among the frame's background pixels (black when there are none)."""
    counts = {}
    for p in range(0, len(ids), 7):  # every 7th pixel is plenty for a flat background
        if ids[p] == BACKGROUND:
            c = rgb[3 * p:3 * p + 3]
            counts[c] = counts.get(c, 0) + 1
    return max(counts, key=counts.get) if counts else b"\0\0\0"


def image_coverage(exact_ids, rgb, background):
    """Share of the exact frame's geometry pixels where `rgb` is not the background colour."""
    shown = geometry = 0
    for p, i in enumerate(exact_ids):
        if i != BACKGROUND:
            geometry += 1
            if rgb[3 * p:3 * p + 3] != background:
                shown += 1
    return shown / geometry if geometry else 1.0


def frame_file(d, kind, f):
    return os.path.join(d, kind, f"frame_{f:05d}.{kind}")


def percentile(values, q):
    v = sorted(values)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))] if v else float("nan")


def compare(exact_dir, exact_frames, run_dir, args, exact_cache):
    frames, summary = read_report(os.path.join(run_dir, "report.jsonl"))
    n = min(len(frames), len(exact_frames))
    if n == 0:
        raise BadInput(f"{run_dir}/report.jsonl: no frames")
    pixels = frames[0]["pixels"]
    psnrs, agree, cover, image_cover, proxy_wrong, proxy_share, samples = [], [], [], [], [], [], []
    overdraw, overdraw_pixels, psnrs_ss = [], 0, []
    first_full, first_full_ms, elapsed = None, None, 0.0
    for f in range(n):
        elapsed += frames[f]["frame_ms"]
        if f not in exact_cache:
            w, h, rgb = read_png(frame_file(exact_dir, "png", f))
            if w * h != pixels:
                raise BadInput(f"{frame_file(exact_dir, 'png', f)}: {w}x{h}, the walk has {pixels} pixels")
            exact_ids = read_ids(frame_file(exact_dir, "ids", f), pixels)
            exact_cache[f] = (w, h, rgb, exact_ids, background_colour(rgb, exact_ids))
        w, h, exact_rgb, exact_ids, background = exact_cache[f]
        ids = read_ids(frame_file(run_dir, "ids", f), pixels)
        geometry = pixels - exact_ids.count(BACKGROUND)
        both = sum(map(operator.and_, map(operator.ne, exact_ids, itertools.repeat(BACKGROUND)),
                       map(operator.ne, ids, itertools.repeat(BACKGROUND))))
        coverage = both / geometry if geometry else 1.0
        if first_full is None and coverage >= 0.99:
            first_full, first_full_ms = f, elapsed
        if f < args.first:
            continue
        cover.append(coverage)
        equal = sum(map(operator.eq, exact_ids, ids))
        agree.append(equal / pixels)
        proxy = frames[f].get("proxy_pixels", 0)
        proxy_share.append(proxy / pixels)
        samples.append(frames[f]["samples"] / pixels)
        if proxy > 0:
            # Geometry in both frames, other ids: pixels naming another primitive.
            other = both - sum(map(operator.and_, map(operator.eq, exact_ids, ids),
                                   map(operator.ne, ids, itertools.repeat(BACKGROUND))))
            proxy_wrong.append(min(1.0, other / proxy))
        _, _, rgb = read_png(frame_file(run_dir, "png", f))
        psnrs.append(psnr(exact_rgb, rgb, args.cap))
        if args.supersampled:
            if ("ss", f) not in exact_cache:
                sw, sh, srgb = read_png(frame_file(args.supersampled, "png", f))
                if (sw, sh) != (2 * w, 2 * h):
                    raise BadInput(f"{frame_file(args.supersampled, 'png', f)}: {sw}x{sh}, expected {2 * w}x{2 * h}")
                exact_cache[("ss", f)] = box_down2(sw, sh, srgb)
            psnrs_ss.append(psnr_float(exact_cache[("ss", f)], rgb, args.cap))
        image_cover.append(image_coverage(exact_ids, rgb, background))
        if ("dt", f) not in exact_cache:
            exact_cache[("dt", f)] = None

        def field(f=f, exact_ids=exact_ids, w=w, h=h):
            if exact_cache[("dt", f)] is None:
                exact_cache[("dt", f)] = distance_to_geometry(exact_ids, w, h)
            return exact_cache[("dt", f)]

        d = overdraw_distances(exact_ids, ids, w, h, field)
        overdraw_pixels += len(d)
        overdraw.extend(d)
    mean = lambda v: sum(v) / len(v) if v else float("nan")
    return {
        "frames": n,
        "compared_from": args.first,
        "p50_frame_ms": summary["p50_frame_ms"],
        "p95_frame_ms": summary["p95_frame_ms"],
        "bytes_read_mib": summary["total_bytes_read"] / 1048576.0,
        "max_resident_mib": summary["max_resident_bytes"] / 1048576.0,
        "peak_rss_mib": summary.get("peak_rss_mib", float("nan")),
        "max_parked": max((fr.get("parked", 0) for fr in frames), default=0),
        "mean_psnr_db": mean(psnrs),
        "min_psnr_db": min(psnrs) if psnrs else float("nan"),
        "mean_psnr_4spp_db": mean(psnrs_ss) if psnrs_ss else None,
        "identical_frames": sum(1 for p in psnrs if p >= args.cap),
        "mean_id_agreement": mean(agree),
        "mean_coverage": mean(cover),
        "min_coverage": min(cover) if cover else float("nan"),
        "mean_image_coverage": mean(image_cover),
        "min_image_coverage": min(image_cover) if image_cover else float("nan"),
        "black_frames": sum(1 for c in image_cover if c < 0.01),
        "first_full_frame": first_full,
        "first_full_ms": first_full_ms,
        "mean_samples_share": mean(samples),
        "mean_proxy_share": mean(proxy_share),
        "proxy_ids_differing": mean(proxy_wrong) if proxy_wrong else None,
        "overdraw_pixels_per_frame": overdraw_pixels / max(1, len(psnrs)),
        "overdraw_mean_px": mean(overdraw) if overdraw else 0.0,
        "overdraw_p95_px": percentile(overdraw, 0.95) if overdraw else 0.0,
        "overdraw_max_px": max(overdraw) if overdraw else 0.0,
    }


COLUMNS = [
    ("T", "{}"), ("p50 ms", "{:.1f}"), ("p95 ms", "{:.1f}"), ("read MiB", "{:.1f}"), ("resident MiB", "{:.1f}"),
    ("PSNR dB", "{:.1f}"), ("min PSNR", "{:.1f}"), ("PSNR 4spp", "{}"), ("ids agree", "{:.3f}"), ("coverage", "{:.4f}"),
    ("min cov.", "{:.4f}"), ("image cov.", "{:.4f}"), ("min image cov.", "{:.4f}"), ("black frames", "{}"),
    ("first >=99 %", "{}"),
    ("proxy px", "{:.3f}"), ("proxy ids differ", "{}"),
    ("overdraw px/frame", "{:.0f}"), ("overdraw dist mean/p95/max", "{}"), ("samples", "{:.3f}"),
    ("peak RSS MiB", "{:.0f}"), ("parked", "{}"),
]


def cells(label, r):
    first = "never" if r["first_full_frame"] is None else f"{r['first_full_frame']} ({r['first_full_ms']:.0f} ms)"
    differ = "-" if r["proxy_ids_differing"] is None else f"{r['proxy_ids_differing']:.3f}"
    dist = f"{r['overdraw_mean_px']:.1f}/{r['overdraw_p95_px']:.1f}/{r['overdraw_max_px']:.1f}"
    ss = "-" if r["mean_psnr_4spp_db"] is None else f"{r['mean_psnr_4spp_db']:.1f}"
    values = [label, r["p50_frame_ms"], r["p95_frame_ms"], r["bytes_read_mib"], r["max_resident_mib"],
              r["mean_psnr_db"], r["min_psnr_db"], ss, r["mean_id_agreement"], r["mean_coverage"], r["min_coverage"],
              r["mean_image_coverage"], r["min_image_coverage"], r["black_frames"], first,
              r["mean_proxy_share"], differ,
              r["overdraw_pixels_per_frame"], dist, r["mean_samples_share"], r["peak_rss_mib"], r["max_parked"]]
    return [fmt.format(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)
            for (_, fmt), v in zip(COLUMNS, values)]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--exact", required=True, help="the exact run's directory (T = 0, --sync-paging)")
    p.add_argument("--run", action="append", default=[], metavar="T=DIR", help="a run to compare (repeatable)")
    p.add_argument("--label", default="", help="the walk's name, for the outputs")
    p.add_argument("--from", dest="first", type=int, default=2, help="first frame of the means (default 2)")
    p.add_argument("--cap", type=float, default=99.0, help="PSNR of identical frames, dB (default 99)")
    p.add_argument("--tsv", help="append the table's rows here (tab-separated, with the walk's label)")
    p.add_argument("--markdown", help="write the Markdown table here (default: stdout)")
    p.add_argument("--json", help="append one JSON line per run here")
    p.add_argument("--supersampled", metavar="DIR",
                   help="the exact walk at twice the width and height (its png/): PSNR against its 2x2 means too")
    p.add_argument("--pair", action="append", default=[], metavar="T:FRAME:OUT.png",
                   help="write run T's frame FRAME beside the exact one (repeatable)")
    try:
        args = p.parse_args()
    except SystemExit as e:
        sys.exit(0 if e.code == 0 else 2)
    runs = []
    for r in args.run:
        if "=" not in r:
            print(f"frame_compare: --run {r}: expected T=DIR", file=sys.stderr)
            sys.exit(2)
        runs.append(r.split("=", 1))
    pairs = []
    for q in args.pair:
        parts = q.split(":", 2)
        if len(parts) != 3 or not parts[1].isdigit() or parts[0] not in [t for t, _ in runs]:
            print(f"frame_compare: --pair {q}: expected T:FRAME:OUT.png with T one of the runs", file=sys.stderr)
            sys.exit(2)
        pairs.append((parts[0], int(parts[1]), parts[2]))
    if not runs or args.first < 0:
        print("frame_compare: need --run T=DIR and --from >= 0", file=sys.stderr)
        sys.exit(2)
    try:
        exact_frames, _ = read_report(os.path.join(args.exact, "report.jsonl"))
        cache = {}
        exact = compare(args.exact, exact_frames, args.exact, args, cache)
        results = [("exact (sync)", exact)] + [(t, compare(args.exact, exact_frames, d, args, cache)) for t, d in runs]
        for t, f, out in pairs:
            run_dir = dict(runs)[t]
            left = read_png(frame_file(run_dir, "png", f))
            write_pair(out, left, read_png(frame_file(args.exact, "png", f)))
    except BadInput as e:
        print(f"frame_compare: {e}", file=sys.stderr)
        sys.exit(1)
    header = [c for c, _ in COLUMNS]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cells(t, r)) + " |" for t, r in results]
    text = "\n".join(lines) + "\n"
    if args.markdown:
        open(args.markdown, "w").write(text)
    else:
        sys.stdout.write(text)
    if args.tsv:
        new = not os.path.exists(args.tsv)
        with open(args.tsv, "a") as f:
            if new:
                f.write("walk\t" + "\t".join(header) + "\n")
            for t, r in results:
                f.write(args.label + "\t" + "\t".join(cells(t, r)) + "\n")
    if args.json:
        with open(args.json, "a") as f:
            for t, r in results:
                f.write(json.dumps({"walk": args.label, "pixel_error": t, **r}) + "\n")


if __name__ == "__main__":
    main()
