"""Fixtures of the phone-client tests: ``findme app`` in a subprocess, headless Chromium.

The browser is Debian's /usr/bin/chromium driven by Playwright (never a downloaded
browser); the browser tests are skipped, saying why, when either is missing. Screenshots go
to a temporary folder (or $FINDME_WEB_SHOTS) and are listed at the end of the run.
"""

from __future__ import annotations

import os
import queue
import signal
import socket
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
#: Flags that work on these machines (no sandbox as root, no network for Chromium's own
#: background services).
CHROMIUM_ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]
SHOTS: list[str] = []


def pytest_terminal_summary(terminalreporter):
    if SHOTS:
        terminalreporter.write_line("web test screenshots:")
        for p in SHOTS:
            terminalreporter.write_line(f"  {p}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class App:
    url: str
    endpoint: str
    proc: subprocess.Popen
    stderr: Path
    recordings: Path

    def log(self) -> str:
        return self.stderr.read_text()[-4000:]


def start_app(tmp: Path, **popen) -> App:
    """``findme app`` on a free HTTP port, with its bus listening for the test's own peer;
    returns once it has printed its readiness line (``popen``: more Popen arguments)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    err = tmp / "stderr.txt"
    with open(err, "w") as ef:
        proc = subprocess.Popen(
            [sys.executable, "-m", "findme.cli", "app", "--http", "127.0.0.1:0",
             "--listen", endpoint, "--out", str(tmp / "recordings")],
            cwd=REPO, stdout=subprocess.PIPE, stderr=ef, text=True, **popen)
    lines: queue.Queue = queue.Queue()

    def read():
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=read, daemon=True).start()
    url = None
    while url is None:   # the readiness line: "findme app: serving http://... (...)"
        try:
            line = lines.get(timeout=60)
        except queue.Empty:
            line = None
        if line is None:
            proc.kill()
            pytest.fail(f"findme app did not report readiness; stderr:\n{err.read_text()}")
        if "serving " in line:
            url = line.split("serving ", 1)[1].split()[0]
    return App(url, endpoint, proc, err, tmp / "recordings")


def stop_app(a: App) -> None:
    """SIGTERM; it must stop cleanly (exit 0) within 20 s."""
    a.proc.send_signal(signal.SIGTERM)
    try:
        code = a.proc.wait(20)
    except subprocess.TimeoutExpired:
        a.proc.kill()
        pytest.fail(f"findme app did not stop on SIGTERM; stderr:\n{a.log()}")
    assert code == 0, f"findme app exited {code}; stderr:\n{a.log()}"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    """``findme app`` for the module's tests (see ``start_app``)."""
    a = start_app(tmp_path_factory.mktemp("app"))
    yield a
    stop_app(a)


@pytest.fixture(scope="module")
def browser():
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is missing (apt-get install -y chromium chromium-driver)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the Python playwright driver is missing (pip install playwright)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    d = Path(os.environ["FINDME_WEB_SHOTS"]) if os.environ.get("FINDME_WEB_SHOTS") else \
        tmp_path_factory.mktemp("web-shots")
    d.mkdir(parents=True, exist_ok=True)

    def shot(page, name: str, at: str | None = None, settled: bool = True) -> Path:
        """What the user sees, scrolled to ``at`` (a selector) when given; ``settled``:
        once the busy indicator is gone (the server has answered everything asked)."""
        if settled:   # a function, not an expression: the page's CSP forbids eval
            from playwright.sync_api import TimeoutError as PlaywrightTimeout
            try:
                page.wait_for_function("() => !document.body.dataset.busy")
            except PlaywrightTimeout:
                busy = page.evaluate("() => document.body.dataset.busy")
                raise AssertionError(f"{name}: the page is still busy with {busy!r}") from None
        if at:
            page.locator(at).first.evaluate("e => e.scrollIntoView({block: 'start'})")
        path = d / f"{name}.png"
        page.screenshot(path=str(path))
        SHOTS.append(str(path))
        return path
    return shot
