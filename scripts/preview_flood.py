"""The preview under a flood of debug-view requests whose clients give up
(issue 14, item 10): 200 requests for /aov.png, each abandoned after 5 s,
while a normal request is timed; prints the server's peak memory and
threads, how long it kept working after the clients left, and what it kept.

Usage: python3 preview_flood.py PRISM SCENE [WIDTH HEIGHT]
The scene is copied and resized (default 1280x960) so that a view takes
seconds. Linux only (reads /proc).
"""

import os
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time

PRISM, SCENE = sys.argv[1:3]
WIDTH, HEIGHT = (int(v) for v in sys.argv[3:5]) if len(sys.argv) > 4 else (1280, 960)
VIEWS = ["normal", "depth", "object", "material", "bounces", "feelers", "time"]

work = tempfile.mkdtemp()
text = open(SCENE).read()
text = re.sub(r"(?m)^width = \d+", f"width = {WIDTH}", text)
text = re.sub(r"(?m)^height = \d+", f"height = {HEIGHT}", text)
scene = os.path.join(work, "scene.toml")
open(scene, "w").write(text)
server = subprocess.Popen([PRISM, "serve", scene, "--port", "0"], stdout=subprocess.PIPE,
                          stderr=subprocess.DEVNULL, text=True)
addr = re.search(r"http://([^/]+)/", server.stdout.readline()).group(1)
host, port = addr.rsplit(":", 1)


def proc(field):
    for line in open(f"/proc/{server.pid}/status"):
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def cpu_seconds():
    parts = open(f"/proc/{server.pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(parts[11]) + int(parts[12])) / os.sysconf("SC_CLK_TCK")


def get(path, timeout):
    s = socket.create_connection((host, int(port)), timeout=timeout)
    s.sendall(f"GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n".encode())
    data = b""
    try:
        while chunk := s.recv(65536):
            data += chunk
    finally:
        s.close()
    return data


def wait_idle():
    """Seconds until the server uses less than 5% of a core."""
    start = time.time()
    while True:
        a = cpu_seconds()
        time.sleep(1)
        if cpu_seconds() - a < 0.05:
            return time.time() - start - 1


wait_idle()  # the preview's own render
rss0 = proc("VmRSS")
peak = {"rss": 0, "threads": 0}
stop = False


def sample():
    while not stop:
        peak["rss"] = max(peak["rss"], proc("VmRSS"))
        peak["threads"] = max(peak["threads"], proc("Threads"))
        time.sleep(0.05)


def abandoned(i):
    try:
        get(f"/aov.png?name={VIEWS[i % len(VIEWS)]}&t={i}", 5)
    except OSError:
        pass  # gave up after 5 s


sampler = threading.Thread(target=sample)
sampler.start()
flood = [threading.Thread(target=abandoned, args=(i,)) for i in range(200)]
for t in flood:
    t.start()
time.sleep(1)
t0 = time.time()
normal = get("/app.css", 60)
latency = time.time() - t0
for t in flood:
    t.join()
left = time.time()
busy_after = wait_idle()
stop = True
sampler.join()
rss_after = proc("VmRSS")
print(f"scene {WIDTH}x{HEIGHT}; before the flood: RSS {rss0 / 1024:.0f} MB")
print(f"normal request (GET /app.css) during the flood: {latency * 1000:.0f} ms, "
      f"{normal.split(b' ')[1].decode()}")
print(f"peak during the flood: RSS {peak['rss'] / 1024:.0f} MB, {peak['threads']} threads")
print(f"kept working {busy_after:.1f} s after the last client gave up")
print(f"afterwards: RSS {rss_after / 1024:.0f} MB, {proc('Threads')} threads")
server.kill()
