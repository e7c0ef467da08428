#!/usr/bin/env python3
"""Draws the link position and the following error of every axis from a recording of the arm.

    modbot up examples/arm.lua --record arm.h5 &       # then switch to ptp, let it move, stop
    python3 examples/plot_recording.py arm.h5           # writes arm.png beside it
    python3 examples/plot_recording.py arm.h5 --summary # numbers only (no matplotlib needed)

The recording is modbot's HDF5 file (see docs/recorder.md): `time` (s), of
shape (ticks,), and per signal a 2-D dataset of ticks x axes; the following error is the position the drives were
commanded to (`robot.demand_position`) minus where the links are (`robot.link_position`).
Needs h5py and numpy; the plot also matplotlib.
"""

import argparse
import sys

import h5py
import numpy as np

LINK = "robot.link_position"
DEMAND = "robot.demand_position"


def load(path):
    """(time, link position, following error, generation), each trimmed to the complete rows."""
    # As a SWMR reader: opens a recording while it is written, and one whose recorder was
    # killed before its mark was taken off, as well as a finished one.
    with h5py.File(path, "r", swmr=True) as f:
        rows = len(f["tick"])  # the count of rows every dataset holds
        time = f["time"][:rows]
        link = f[LINK][:rows]
        demand = f[DEMAND][:rows]
        generation = f["generation"][:rows]
    return time, link, demand - link, generation


def summary(path):
    time, link, error, generation = load(path)
    print(f"rows {len(time)}  from {time[0]:.3f} s to {time[-1]:.3f} s")
    print(f"generations {' '.join(str(g) for g in np.unique(generation))}")
    for axis in range(link.shape[1]):
        moved = link[:, axis].max() - link[:, axis].min()
        worst = np.abs(error[:, axis]).max()
        print(f"axis {axis}  moved {moved:.4f} rad  max |following error| {worst:.6f} rad")


def plot(path, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    time, link, error, _ = load(path)
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(10, 7))
    for axis in range(link.shape[1]):
        top.plot(time, link[:, axis], label=f"axis {axis}")
        bottom.plot(time, error[:, axis] * 1e3, label=f"axis {axis}")
    top.set_ylabel("link position (rad)")
    bottom.set_ylabel("following error (mrad)")
    bottom.set_xlabel("time (s)")
    top.legend(loc="upper right", ncol=3, fontsize="small")
    top.set_title(path)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", help="the HDF5 recording")
    parser.add_argument("--out", help="the image to write (default: FILE with .png)")
    parser.add_argument("--summary", action="store_true", help="print numbers, draw nothing")
    args = parser.parse_args()
    if args.summary:
        summary(args.file)
    else:
        out = args.out or (args.file.rsplit(".", 1)[0] + ".png")
        plot(args.file, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
