#!/usr/bin/env python3
"""Ctrl-C latency per stage (issue 49, must-show 4).

Runs `voltrack convert INPUT -o OUT.glb [ARGS]` once per stage, with stderr
piped (so voltrack prints a line as each stage starts), sends one SIGINT
DELAY seconds after the stage's line appears, and prints how long the
process took to exit after the signal and its exit code (130 expected).

    python3 contrib/ctrl_c_per_stage.py VOLTRACK INPUT [--delay S] [--stages a,b] [-- ARGS...]
"""
import argparse, os, signal, subprocess, sys, tempfile, threading, time

STAGES = ["read", "voxelize", "track", "refine", "deform", "conform", "fit", "export"]


def one(voltrack, inp, stage, delay, extra):
    out = os.path.join(tempfile.mkdtemp(prefix="ctrlc-"), "out.glb")
    p = subprocess.Popen([voltrack, "convert", inp, "-o", out, *extra],
                         stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    seen = threading.Event()
    lines = []

    def watch():
        for line in p.stderr:
            lines.append(line.rstrip())
            if line.startswith(f"voltrack: {stage} ..."):
                seen.set()
    t = threading.Thread(target=watch, daemon=True)
    t.start()
    while not seen.is_set() and p.poll() is None:
        time.sleep(0.005)
    if p.poll() is not None:
        return None, p.returncode, "finished before the stage"
    time.sleep(delay)
    if p.poll() is not None:
        return None, p.returncode, "finished within the delay"
    sent = time.monotonic()
    p.send_signal(signal.SIGINT)
    code = p.wait()
    took = time.monotonic() - sent
    t.join(timeout=1)
    started = [l for l in lines if l.endswith(" ...")]
    at = started[-1].split()[1] if started else "?"
    return took, code, f"stage running at the signal: {at}; output written: {os.path.exists(out)}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("voltrack")
    ap.add_argument("input")
    ap.add_argument("--delay", type=float, default=0.5)
    ap.add_argument("--stages", default=",".join(STAGES))
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    print(f"| stage | seconds to exit after SIGINT | exit code | note |")
    print(f"|---|---|---|---|")
    for stage in a.stages.split(","):
        took, code, note = one(a.voltrack, a.input, stage, a.delay, extra)
        shown = "-" if took is None else f"{took:.3f}"
        print(f"| {stage} | {shown} | {code} | {note} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
