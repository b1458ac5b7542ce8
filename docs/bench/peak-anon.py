#!/usr/bin/env python3
"""Runs a command and reports its peak anonymous memory.

    docs/bench/peak-anon.py COMMAND [ARGS...]

Samples `RssAnon` (and `RssFile`) of /proc/PID/status every millisecond while the
command runs and prints, on stderr after the command's own output, the wall time,
the peak RssAnon and the peak RssFile (the file pages mapped in: the page cache the
renderer reads through, which the OS may reclaim). The kernel keeps no peak of
RssAnon itself (VmHWM counts file pages too), hence the sampling; a spike shorter
than a millisecond can be missed.
"""
import subprocess
import sys
import time


def field(status, name):
    for line in status.splitlines():
        if line.startswith(name + ":"):
            return int(line.split()[1])
    return 0


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    start = time.monotonic()
    child = subprocess.Popen(sys.argv[1:])
    peak_anon = peak_file = 0
    path = f"/proc/{child.pid}/status"
    while child.poll() is None:
        try:
            with open(path) as f:
                status = f.read()
        except OSError:
            break
        peak_anon = max(peak_anon, field(status, "RssAnon"))
        peak_file = max(peak_file, field(status, "RssFile"))
        time.sleep(0.001)
    code = child.wait()
    wall = time.monotonic() - start
    print(
        f"wall {wall:.2f} s, peak RssAnon {peak_anon / 1024:.1f} MiB, "
        f"peak RssFile {peak_file / 1024:.1f} MiB",
        file=sys.stderr,
    )
    sys.exit(code)


if __name__ == "__main__":
    main()
