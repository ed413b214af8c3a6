"""A small LAN of "hosts" on this machine: one Linux network namespace per host, each with
its own eth0 and IP address on a bridge (in a namespace of its own, so the machine's own
network is never touched), and its own /etc/hosts (``ip netns exec`` mounts
/etc/netns/<name>/hosts over /etc/hosts), so names resolve as on a real network.

Needs root and ``ip`` (iproute2). ``Lan.close`` removes everything it made (namespaces,
their links, /etc/netns/<name>), also after a failure.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import uuid
from pathlib import Path

SUBNET = "10.200.0"


def _ip(*args: str) -> None:
    p = subprocess.run(["ip", *args], capture_output=True, text=True)
    if p.returncode:
        raise OSError(f"ip {' '.join(args)}: {p.stderr.strip()}")


def why_not() -> str | None:
    """Why namespaces cannot be made here, or None when they can (tries one)."""
    if shutil.which("ip") is None:
        return "the ip command (iproute2) is not installed"
    name = f"fmprobe-{uuid.uuid4().hex[:6]}"
    try:
        _ip("netns", "add", name)
    except OSError as e:
        return f"cannot create a network namespace ({e}); needs root"
    _ip("netns", "del", name)
    return None


class Lan:
    """Hosts ``{name: last octet}`` on 10.200.0.0/24; ``names`` maps host names (as in
    certificates) to hosts, written to every host's /etc/hosts."""

    def __init__(self, hosts: dict[str, int], names: dict[str, str]):
        self.tag = uuid.uuid4().hex[:5]
        self.ns = {h: f"fm{self.tag}-{h}" for h in hosts}
        self.ip = {h: f"{SUBNET}.{o}" for h, o in hosts.items()}
        self.bridge_ns = f"fm{self.tag}-lan"
        self.procs: list[subprocess.Popen] = []
        made = [self.bridge_ns]
        try:
            _ip("netns", "add", self.bridge_ns)
            _ip("-n", self.bridge_ns, "link", "add", "br0", "type", "bridge")
            _ip("-n", self.bridge_ns, "link", "set", "br0", "up")
            lines = ["127.0.0.1 localhost"] + [f"{self.ip[h]} {n}" for n, h in names.items()]
            for h, ns in self.ns.items():
                made.append(ns)
                _ip("netns", "add", ns)
                etc = Path("/etc/netns") / ns
                etc.mkdir(parents=True, exist_ok=True)
                (etc / "hosts").write_text("\n".join(lines) + "\n")
                port = f"fm{self.tag}{h[:4]}"
                _ip("link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns)
                _ip("link", "set", port, "netns", self.bridge_ns)
                _ip("-n", self.bridge_ns, "link", "set", port, "master", "br0", "up")
                _ip("-n", ns, "addr", "add", f"{self.ip[h]}/24", "dev", "eth0")
                _ip("-n", ns, "link", "set", "eth0", "up")
                _ip("-n", ns, "link", "set", "lo", "up")
        except BaseException:
            self._remove(made)
            raise
        self._made = made

    def link(self, host: str, up: bool) -> None:
        """Plug (``up``) or unplug the host's network cable (its eth0)."""
        _ip("-n", self.ns[host], "link", "set", "eth0", "up" if up else "down")

    def spawn(self, host: str, *args, log: Path) -> subprocess.Popen:
        """``findme ARGS`` on a host; stderr+stdout to ``log``, lines in ``proc.lines``."""
        cmd = ["ip", "netns", "exec", self.ns[host], sys.executable, "-m", "findme.cli",
               *map(str, args)]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        proc.lines, proc.new_line, proc.host = [], threading.Condition(), host
        out = open(log, "w")   # noqa: SIM115 - closed by the drain thread

        def drain():
            with out:
                for line in proc.stdout:
                    out.write(line)
                    out.flush()
                    with proc.new_line:
                        proc.lines.append(line)
                        proc.new_line.notify_all()
        threading.Thread(target=drain, daemon=True).start()
        self.procs.append(proc)
        return proc

    def wrapper(self, host: str, program: str, path: Path, env: dict) -> Path:
        """An executable that runs ``program`` in the host's namespace (for tools that start
        a program themselves, e.g. Playwright starting Chromium)."""
        exports = " ".join(f"{k}={v}" for k, v in env.items())
        path.write_text(f"#!/bin/sh\nexec ip netns exec {self.ns[host]} env {exports} "
                        f"{program} \"$@\"\n")
        path.chmod(0o755)
        return path

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.kill()
                p.wait(10)
        self._remove(self._made)

    @staticmethod
    def _remove(made) -> None:
        for ns in made:
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
            shutil.rmtree(Path("/etc/netns") / ns, ignore_errors=True)
