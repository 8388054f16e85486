"""Interrupt `hil run` at random moments and compare what the MCAP holds with what metrics.json counts.

`python -m tests.runner.interrupt_runs --tries 100` runs the 100-try check (in-process native
loop, native loop over UDP to a spawned target, Python loop; SIGINT or SIGTERM, to `hil` or to its process
group as a terminal's Ctrl-C, at a moment drawn at random) and prints
one line per try and the tally; exit 1 if any try lost or invented a period. The test suite runs a few tries
(tests/runner/test_interrupt_log.py).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.hil.runlog.reader import read_periods

if TYPE_CHECKING:
    from tests.runner.foreign_zygote import ForeignTarget

#: the run variants: name -> `hil run` options (long enough that a signal lands mid-run)
VARIANTS: dict[str, tuple[str, ...]] = {
    "inproc": ("--duration", "60", "--settle", "0"),
    "udp-spawn": ("--link", "udp", "--target", "spawn", "--duration", "30", "--settle", "0"),
    "python": ("--loop", "python", "--duration", "30", "--settle", "0"),
}


@dataclass
class Try:
    """One interrupted run: the signal, when it was sent after the start [s] and what was found."""

    variant: str
    sig: str
    group: bool
    delay_s: float
    rc: int
    mcap_periods: int | None
    metrics_periods: int | None  # total_periods
    end_period: int | None
    seq_ok: bool
    stderr_tail: str
    out_created: bool = True


    @property
    def before_hil(self) -> bool:
        """The signal came while the Python interpreter itself started, before `hil`'s code ran (the first
        ~50 ms): killed by it, or Python's own "Fatal Python error: init_import_site"; nothing written."""
        python_start = self.rc == 1 and "Fatal Python error: init_import_site" in self.stderr_tail
        killed = self.rc == -getattr(signal, self.sig) and not self.stderr_tail
        return not self.out_created and (killed or python_start)

    @property
    def ok(self) -> bool:
        """MCAP periods = end_period + 1 = total_periods, seq 0..n-1 without a gap, exit 130 or 0, no traceback;
        or, interrupted before the target was connected, no metrics.json and no period in the MCAP (said on
        stderr); or `before_hil`."""
        if self.before_hil:
            return True
        if "Traceback" in self.stderr_tail or self.rc not in (0, 130):
            return False
        if self.metrics_periods is None:
            return self.rc == 130 and not self.mcap_periods
        return (self.seq_ok and self.end_period is not None
                and self.mcap_periods == self.end_period + 1 == self.metrics_periods)


def _default_sigint() -> None:
    """In the child before exec: SIGINT to its default, so `hil` installs its handler even when this runs where
    SIGINT is ignored (a background job of a non-interactive shell, as CI may be)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def cpu_seconds(pid: int) -> float:
    """CPU seconds (user + system) process `pid` has used; 0.0 once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime


def _execed(pid: int, marker: bytes) -> bool:
    try:
        return marker in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def wait_cpu(proc: subprocess.Popen[bytes], cpu_s: float, timeout_s: float, marker: bytes = b"pmsm_hil") -> None:
    """Until `proc` has used `cpu_s` CPU seconds since it exec'd its command (its command line holds `marker`),
    or ended, or `timeout_s` of wall time passed: a delay that means the same progress on an idle and on a busy
    machine. (Counted from the exec: the CPU of the fork of a large pytest worker before it is not the command's.)"""
    deadline = time.monotonic() + timeout_s
    while proc.poll() is None and not _execed(proc.pid, marker) and time.monotonic() < deadline:
        time.sleep(0.001)
    cpu0 = cpu_seconds(proc.pid)
    while proc.poll() is None and cpu_seconds(proc.pid) - cpu0 < cpu_s and time.monotonic() < deadline:
        time.sleep(0.005)


def interrupt_once(out: Path, variant: str, sig: signal.Signals, delay_s: float, *, group: bool = False,
                   after_bytes: int = 0, timeout_s: float = 120.0, cpu_clock: bool = False,
                   forked: bool = False) -> Try:
    """Start `hil` with `variant` into `out`, send `sig` after `delay_s` (s) to it, or to its whole process group
    (`group`: as a terminal's Ctrl-C or `kill -- -PGID`; the logger and a spawned target get it too), wait for
    it and compare the files. `after_bytes`: count the delay from when run.mcap holds that many bytes (the
    loop runs). `cpu_clock`: the delay is `hil`'s own CPU time (its start-up is CPU-bound: on an idle machine
    about the wall time; on a busy one, the wall time would end while Python itself still starts). `forked`:
    `hil` forked from a process that has made its imports (tests/runner/hil_zygote.py), for a signal mid-run."""
    argv = ["run", *VARIANTS[variant], "--out", str(out)]
    stderr = out.with_name(out.name + ".stderr")
    stderr.parent.mkdir(parents=True, exist_ok=True)
    proc: subprocess.Popen[bytes] | ForeignTarget
    if forked:
        from tests.runner.hil_zygote import start_hil

        proc = start_hil(argv, stderr, session=group)
    else:
        with stderr.open("wb") as err_file:
            proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", *argv],
                                    stdout=subprocess.DEVNULL, stderr=err_file, start_new_session=group,
                                    preexec_fn=_default_sigint)
    mcap = out / "run.mcap"
    deadline = time.monotonic() + timeout_s
    while after_bytes and proc.poll() is None and time.monotonic() < deadline and not (
            mcap.exists() and mcap.stat().st_size >= after_bytes):
        time.sleep(0.01)
    if cpu_clock:
        assert isinstance(proc, subprocess.Popen), "the CPU clock counts from the exec of a fresh process"
        wait_cpu(proc, delay_s, timeout_s)
    else:
        time.sleep(delay_s)
    with contextlib.suppress(ProcessLookupError):  # it ended before the signal
        if group:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    text = stderr.read_bytes().decode(errors="replace")
    metrics_file = out / "metrics.json"
    periods = read_periods(mcap) if mcap.exists() else None
    metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else None
    n = None if periods is None else int(periods.shape[0])
    seq_ok = periods is not None and bool((periods["seq"] == range(n or 0)).all())
    assert proc.returncode is not None
    return Try(variant, sig.name, group, delay_s, int(proc.returncode), n,
               None if metrics is None else int(metrics["total_periods"]),
               None if metrics is None else int(metrics["end_period"]), seq_ok, text[-2000:], out.exists())


def main(argv: list[str] | None = None) -> int:
    """Run `--tries` random interruptions; print each and the tally."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--tries", type=int, default=100)
    p.add_argument("--seed", type=int, default=26)
    p.add_argument("--max-delay", type=float, default=3.0, help="latest signal after the start [s]")
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--dir", type=Path, default=Path("/tmp/hil-interrupt-runs"))
    args = p.parse_args(argv)
    rng = random.Random(args.seed)
    variants = args.variants.split(",")
    bad = before_hil = 0
    by_variant: dict[str, list[int]] = {}
    for k in range(args.tries):
        variant = variants[k % len(variants)]
        sig = rng.choice((signal.SIGINT, signal.SIGTERM))
        group = rng.random() < 0.5
        delay = rng.uniform(0.0, args.max_delay)
        out = args.dir / f"try{k:03d}"
        shutil.rmtree(out, ignore_errors=True)
        t = interrupt_once(out, variant, sig, delay, group=group)
        tally = by_variant.setdefault(variant, [0, 0])
        tally[0] += 1
        tally[1] += 0 if t.ok else 1
        bad += 0 if t.ok else 1
        before_hil += t.before_hil
        print(f"{k:3d} {variant:9s} {t.sig:7s} to {'group' if group else 'hil  '} after {delay:5.2f} s: "
              f"exit {t.rc:3d}{' (before hil ran)' * t.before_hil}, mcap {t.mcap_periods}, "
              f"end_period+1 {None if t.end_period is None else t.end_period + 1}, total {t.metrics_periods}, "
              f"seq {'ok' if t.seq_ok else 'GAP'} -> {'ok' if t.ok else 'LOST'}", flush=True)
        if not t.ok:
            print("    " + t.stderr_tail.strip().replace("\n", "\n    "), flush=True)
    for variant, (n, lost) in by_variant.items():
        print(f"{variant}: {n - lost}/{n} consistent")
    print(f"all: {args.tries - bad}/{args.tries} consistent ({before_hil} signalled before hil ran: no file)")
    return 1 if bad else 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
