#!/usr/bin/env python3
"""The editor's server-side frame without a browser: POST /api/transform in
a loop and report the medians of the server's `compute_s` and of the round
trip. With several editor URLs (e.g. two builds serving the same mesh and
constraints), the rounds alternate between them so that a change in the
host's speed affects each alike.

    lse-deform edit MESH --constraints SCENE.json --port 0   # one per build
    python3 experiments/editor_frames.py URL [URL ...] [--group 'handle 1'] [--frames 300] [--rounds 5]

Each URL is the one `lse-deform edit` prints (`http://HOST:PORT/?token=T`);
the token goes with every request as `Authorization: Bearer T`.

Standard library only. The transform of frame k is a translation along a
circle of radius 0.1 (mesh units), as the bench's drag.
"""
import argparse
import json
import math
import statistics
import time
import urllib.parse
import urllib.request

# Base URL (without the token) -> the token of that server.
TOKENS = {}


def base_of(printed):
    """The server's base URL from the URL `lse-deform edit` printed,
    remembering its token."""
    parts = urllib.parse.urlsplit(printed)
    token = urllib.parse.parse_qs(parts.query).get("token", [""])[0]
    if not token:
        raise SystemExit(f"{printed}: no ?token= (give the URL that lse-deform edit printed)")
    base = f"{parts.scheme}://{parts.netloc}"
    TOKENS[base] = token
    return base


def headers(url, **more):
    return {"authorization": f"Bearer {TOKENS[url]}", **more}


def get(url, path):
    with urllib.request.urlopen(urllib.request.Request(url + path, headers=headers(url))) as r:
        return json.load(r)


def wait_until_idle(url):
    while get(url, "/api/progress").get("busy", False):
        time.sleep(0.5)


def frame(url, group, k):
    a = 0.05 * k
    m = [[1, 0, 0, 0.1 * math.sin(a)], [0, 1, 0, 0.1 * (1 - math.cos(a))], [0, 0, 1, 0]]
    body = json.dumps({"group": group, "matrix": m}).encode()
    request = urllib.request.Request(
        url + "/api/transform", data=body, method="POST",
        headers=headers(url, **{"content-type": "application/json"}))
    t = time.perf_counter()
    with urllib.request.urlopen(request) as r:
        answer = json.load(r)
    return answer["compute_s"], time.perf_counter() - t


def round_of(url, group, frames):
    times = [frame(url, group, k) for k in range(frames)]
    return (statistics.median(c for c, _ in times), statistics.median(r for _, r in times))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("urls", nargs="+")
    p.add_argument("--group", default="handle 1")
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--rounds", type=int, default=5)
    a = p.parse_args()
    urls = [base_of(u) for u in a.urls]
    for u in urls:
        wait_until_idle(u)
        frame(u, a.group, 0)  # the first frame after a selection warms the caches
    medians = {u: [] for u in urls}
    for r in range(a.rounds):
        for u in urls:
            compute, trip = round_of(u, a.group, a.frames)
            medians[u].append(compute)
            print(f"round {r + 1} {u}: server frame median {1e3 * compute:.3f} ms, "
                  f"round trip median {1e3 * trip:.3f} ms")
    for u in urls:
        print(f"{u}: median of the {a.rounds} rounds' medians "
              f"{1e3 * statistics.median(medians[u]):.3f} ms")
    if len(urls) == 2:
        ratios = [x / y for x, y in zip(medians[urls[0]], medians[urls[1]])]
        print(f"first / second, median of the per-round ratios: {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
