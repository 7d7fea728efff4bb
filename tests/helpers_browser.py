"""Open a page in headless Chromium (Debian's ``chromium`` package) and read what it rendered,
through the DevTools protocol over a pipe (``--remote-debugging-pipe``: JSON messages ended by
NUL on file descriptors 3 (commands) and 4 (answers); no websocket library needed).

``open_page`` returns what a test checks: the result of a JavaScript expression evaluated in the
loaded page, the console errors and uncaught exceptions, every network request that was not a
``data:`` or ``file:`` URL, and whether a JavaScript dialog (``alert``) opened. A missing
``chromium`` is a test failure (``make system-deps`` installs it), never a skip.
"""

from __future__ import annotations

import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

#: flags that work on this project's machines (no sandbox as root, no GPU, no background
#: connections: the network is closed and Chromium would retry its services at every start)
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--disable-extensions",
                  "--remote-debugging-pipe"]


def chromium_path() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.fail("chromium is not installed: `make system-deps` installs Debian's chromium "
                    "(apt-get install chromium); the HTML report test needs a real browser")
    return exe


class _Pipe:
    def __init__(self, write_fd: int, read_fd: int) -> None:
        self.write_fd, self.read_fd, self.buffer, self.next_id = write_fd, read_fd, b"", 0
        self.events: list[dict] = []

    def send(self, method: str, params: dict | None = None, session: str | None = None) -> int:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        return self.next_id

    def _read(self, deadline: float) -> dict | None:
        while b"\0" not in self.buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self.read_fd], [], [], left)
            if not ready:
                return None
            chunk = os.read(self.read_fd, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self.buffer += chunk
        raw, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method: str, params: dict | None = None, session: str | None = None,
             timeout_s: float = 30.0) -> dict:
        wanted = self.send(method, params, session)
        deadline = time.monotonic() + timeout_s
        while True:
            message = self._read(deadline)
            if message is None:
                raise TimeoutError(f"no answer to {method} within {timeout_s} s")
            if message.get("id") == wanted:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self.events.append(message)

    def wait_load(self, session: str, timeout_s: float) -> None:
        """Wait for the page's load event; a JavaScript dialog (which would block the load) is
        recorded and dismissed."""
        deadline = time.monotonic() + timeout_s
        seen = 0
        while True:
            for event in self.events[seen:]:
                if event.get("method") == "Page.loadEventFired":
                    return
                if event.get("method") == "Page.javascriptDialogOpening":
                    self.send("Page.handleJavaScriptDialog", {"accept": True}, session)
            seen = len(self.events)
            message = self._read(deadline)
            if message is None:
                raise TimeoutError(f"the page did not load within {timeout_s} s")
            self.events.append(message)

    def drain(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while (message := self._read(deadline)) is not None:
            self.events.append(message)


def _high_pipe() -> tuple[int, int]:
    """A pipe whose ends are numbered above 9, so the child's fds 3 and 4 can be made from
    them without clobbering one of them."""
    ends = []
    for fd in os.pipe():
        ends.append(fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10))
        os.close(fd)
    return ends[0], ends[1]


def open_page(page: Path, expression: str, timeout_s: float = 60.0) -> dict:
    """Load ``page`` (a local file) in headless Chromium, evaluate ``expression`` (JavaScript,
    its value returned as JSON) and report {value, console_errors, requests, dialogs}."""
    exe = chromium_path()
    cmd_r, cmd_w = _high_pipe()
    out_r, out_w = _high_pipe()
    # chromium's helper processes may still write the profile while it is removed
    with tempfile.TemporaryDirectory(prefix="chromium-", ignore_cleanup_errors=True) as profile:
        script = f'exec "$0" "$@" 3<&{cmd_r} 4>&{out_w} {cmd_r}<&- {out_w}>&-'
        proc = subprocess.Popen(
            ["bash", "-c", script, exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
             "about:blank"], pass_fds=(cmd_r, out_w), stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(out_w)
        pipe = _Pipe(cmd_w, out_r)
        try:
            target = pipe.call("Target.createTarget", {"url": "about:blank"},
                               timeout_s=timeout_s)["targetId"]
            session = pipe.call("Target.attachToTarget",
                                {"targetId": target, "flatten": True})["sessionId"]
            for domain in ("Runtime", "Log", "Network", "Page"):
                pipe.call(f"{domain}.enable", session=session)
            pipe.call("Page.navigate", {"url": page.resolve().as_uri()}, session=session)
            pipe.wait_load(session, timeout_s)
            pipe.drain(0.5)  # late console messages
            result = pipe.call("Runtime.evaluate", {"expression": expression,
                                                    "returnByValue": True}, session=session)
            value = result.get("result", {}).get("value")
            events = pipe.events
        finally:
            os.close(cmd_w)
            os.close(out_r)
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    errors = []
    for e in events:
        p = e.get("params", {})
        if e.get("method") == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            errors.append(" ".join(str(a.get("value", a.get("description", "")))
                                   for a in p.get("args", [])))
        elif e.get("method") == "Runtime.exceptionThrown":
            errors.append(str(p.get("exceptionDetails", {}).get("text")))
        elif e.get("method") == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            errors.append(p["entry"].get("text", ""))
    requests = [e["params"]["request"]["url"] for e in events
                if e.get("method") == "Network.requestWillBeSent"
                and not e["params"]["request"]["url"].startswith(("data:", "file:"))]
    dialogs = [e for e in events if e.get("method") == "Page.javascriptDialogOpening"]
    return {"value": value, "console_errors": errors, "requests": requests, "dialogs": dialogs}
