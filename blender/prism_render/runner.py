"""Running the `prism` command: an argument list (never a shell), its
stderr read on a thread so that progress and cancel are polled without
blocking."""

import queue
import re
import subprocess
import threading
import time

PROGRESS = re.compile(r"^prism: progress .*\bpercent=(\d+)")


class Outcome:
    def __init__(self):
        self.returncode = None
        self.cancelled = False
        self.errors = []
        self.warnings = []
        self.log = []


def render(command, on_progress, should_stop, on_poll=None, poll=0.1):
    """Run `command` (a list), calling on_progress(fraction) for each
    progress line and on_poll() now and then, and stopping it when
    should_stop() turns true."""
    out = Outcome()
    try:
        proc = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            errors="replace",
        )
    except OSError as e:
        out.errors.append(f"cannot run {command[0]!r}: {e.strerror or e} "
                          "(set the path to prism in the add-on's preferences)")
        return out
    lines = queue.Queue()

    def pump():
        for line in proc.stderr:
            lines.put(line.rstrip("\n"))
        lines.put(None)

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    stopped_at = None
    finished = False
    polled = time.monotonic()
    while not finished:
        try:
            line = lines.get(timeout=poll)
        except queue.Empty:
            line = ""
        if line is None:
            finished = True
        elif line:
            out.log.append(line)
            m = PROGRESS.match(line)
            if m:
                on_progress(min(100, int(m.group(1))) / 100.0)
            elif line.startswith("warning:"):
                out.warnings.append(line[len("warning:"):].strip())
        if on_poll is not None and stopped_at is None and time.monotonic() - polled >= 0.25:
            polled = time.monotonic()
            on_poll()
        if stopped_at is None and should_stop():
            # SIGTERM: Prism stops at the next row and writes nothing.
            out.cancelled = True
            stopped_at = time.monotonic()
            proc.terminate()
        elif stopped_at is not None and time.monotonic() - stopped_at > 5.0:
            proc.kill()
            stopped_at = float("inf")
    out.returncode = proc.wait()
    reader.join(timeout=1.0)
    if out.returncode != 0 and not out.cancelled:
        # Everything but progress and warnings is the error (Prism writes
        # `file:line:column: message` lines and their context).
        out.errors = [l for l in out.log
                      if not PROGRESS.match(l) and not l.startswith(("warning:", "prism: rendering"))]
        if not out.errors:
            out.errors = [f"prism exited with status {out.returncode}"]
    return out
