#!/usr/bin/env python3
"""simulate.py — replays penumbra's MPI tile scheduler (src/driver/mpi.c) over measured tile
costs, to predict parallel efficiency beyond this 2-core machine (issue 16; bench/RESULTS.md).

Input: a --tile-times file of a one-process, one-thread render (tile x0 y0 x1 y1 seconds), whose
tiles are aggregated into tiles of --tile-size pixels (costs summed: a tile's cost is the sum of
its blocks'; the recorded tiles must divide the simulated ones).

The scheduler, as mpi.c implements it: tiles in row order; rank 0 renders tiles on a thread of
its own, taking the next one the moment it finishes one; every other rank asks rank 0 for a tile
(a first request, then each finished tile's estimates double as the next request) and waits for
the answer. The model of the machine:
  - a message takes `latency` seconds from sender to receiver, plus size / `bandwidth` on rank 0's
    inbound link, which carries one message at a time (every tile's estimates, bytes_per_pixel a
    pixel, arrive through it: this is what a single rank 0 serialises);
  - rank 0's main thread sees a message `poll` / 2 after it arrives on average (while nothing
    comes it sleeps from 50 us doubling up to 1 ms: `poll` 1 ms is the worst case) and handles
    one message at a time, `handle` seconds each;
  - every rank loads the scene and prepares at the same time, in `load` seconds (replicated, as
    penumbra does: a shared file system serving every rank at once is assumed), after an MPI job
    start of `startup` seconds;
  - a tile costs the same on every rank as in the recording (same cores).
Efficiency = one process's time (load + sum of tile costs) / (ranks x the job's time); the render
efficiency leaves load and startup out of both.
"""
import argparse
import heapq
import math


def read_tiles(path):
    tiles = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            _, x0, y0, x1, y1, sec = line.split()
            tiles.append((int(x0), int(y0), int(x1), int(y1), float(sec)))
    return tiles


def aggregate(tiles, size):
    """Tiles of `size` pixels (row order) as (pixels, cost)."""
    agg = {}
    for x0, y0, x1, y1, sec in tiles:
        key = (y0 // size, x0 // size)
        p, c = agg.get(key, (0, 0.0))
        agg[key] = (p + (x1 - x0) * (y1 - y0), c + sec)
    return [agg[k] for k in sorted(agg)]


def simulate(tiles, ranks, m):
    """Makespan of the tile loop (seconds after every rank has loaded)."""
    n = len(tiles)
    nxt = 0
    end = 0.0
    link_free = 0.0  # rank 0's inbound link
    main_free = 0.0  # rank 0's main thread
    local_free = 0.0  # rank 0's renderer thread
    # events: (time a message is sent to rank 0, rank, pixels of the finished tile or 0)
    events = [(0.0, r, 0) for r in range(1, ranks)]
    heapq.heapify(events)
    while events or (nxt < n):
        # rank 0's own renderer takes a tile whenever it is free before the next message is handled
        t_msg = events[0][0] if events else math.inf
        if nxt < n and local_free <= t_msg:
            local_free += tiles[nxt][1]
            end = max(end, local_free)
            nxt += 1
            continue
        if not events:
            break
        sent, r, pixels = heapq.heappop(events)
        arrive = sent + m.latency
        size = 64 + pixels * m.bytes_per_pixel
        arrive = max(arrive, link_free) + size / m.bandwidth
        link_free = arrive
        seen = max(arrive + m.poll / 2, main_free)
        main_free = seen + m.handle
        end = max(end, main_free)
        if nxt < n:
            p, cost = tiles[nxt]
            nxt += 1
            done = main_free + m.latency + cost
            heapq.heappush(events, (done, r, p))
    return max(end, local_free)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("tiles")
    ap.add_argument("--tile-size", type=int, nargs="+", default=[64])
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 16, 64, 256])
    ap.add_argument("--latency", type=float, default=5e-6, help="seconds per message (default 5 us)")
    ap.add_argument("--bandwidth", type=float, default=1.25e9, help="rank 0 inbound bytes/s (10 GbE)")
    ap.add_argument("--poll", type=float, default=1e-3, help="rank 0's longest sleep when idle (mpi.c: 1 ms)")
    ap.add_argument("--handle", type=float, default=5e-6, help="rank 0's seconds per message")
    ap.add_argument("--bytes-per-pixel", type=int, default=136, help="sizeof(pn_pixel_estimate)")
    ap.add_argument("--load", type=float, default=0.0, help="scene load + preparation seconds, every rank")
    ap.add_argument("--startup", type=float, default=0.0, help="MPI job start seconds")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="multiply the recorded tile costs (e.g. 64 for a 64-spp render recorded at 1 spp)")
    m = ap.parse_args()
    raw = [(x0, y0, x1, y1, sec * m.scale) for x0, y0, x1, y1, sec in read_tiles(m.tiles)]
    print("| tile size | tiles | ranks | predicted render s | render efficiency | job s | job efficiency | "
          "rank-0 link busy |")
    print("|---|---|---|---|---|---|---|---|")
    for size in m.tile_size:
        tiles = aggregate(raw, size)
        total = sum(c for _, c in tiles)
        pixels = sum(p for p, _ in tiles)
        for r in m.ranks:
            span = simulate(tiles, r, m) if r > 1 else total
            job = m.startup + m.load + span if r > 1 else m.load + total
            link = (len(tiles) * 64 + pixels * m.bytes_per_pixel) / m.bandwidth
            print("| %d | %d | %d | %.3f | %.1f%% | %.3f | %.1f%% | %.3f s |" % (
                size, len(tiles), r, span, 100 * total / (r * span), job, 100 * (m.load + total) / (r * job),
                link if r > 1 else 0.0))


if __name__ == "__main__":
    main()
