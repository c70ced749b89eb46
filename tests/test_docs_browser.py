"""The built documentation site in a real browser: headless Chromium over the DevTools protocol.

The site (``docs/_build/html`` as ``make docs`` leaves it, else built here into a temporary
folder) is served on 127.0.0.1 and each page is loaded in Chromium. A page passes when every
``<img>`` has loaded (``complete`` with a ``naturalWidth`` above 0) and the page logged no
error: no ``console.error``, no uncaught exception, no failed resource (a missing image, a
script or a MathJax font answered 404 is a ``Log`` error) and no formula that MathJax could
not typeset. Skipped, saying why, where
Chromium or websocket-client is missing; ``make test`` runs it after ``make docs``
(``-m browser``).
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from ias_gym.registration import ENV_SPECS, HARDWARE_ENV_SPECS

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parents[1]
BUILT = ROOT / "docs" / "_build" / "html"
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
TIMEOUT = 60.0  # [s] for a page to load, its images and MathJax included
#: Evaluated in the page once it has loaded: waits for MathJax's typesetting and the fonts.
IMAGES_JS = """(async () => {
  if (window.MathJax && MathJax.startup && MathJax.startup.promise) {
    await MathJax.startup.promise;
  }
  await document.fonts.ready;
  return {
    images: Array.from(document.images).map(i => ({
      src: i.currentSrc || i.src, complete: i.complete, width: i.naturalWidth})),
    mathErrors: Array.from(document.querySelectorAll("mjx-merror")).map(e => e.textContent),
  };
})()"""


def chromium() -> str | None:
    """The path of a Chromium (or Chrome) binary, or ``None``."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def site() -> Iterator[Path]:
    """The built site: ``docs/_build/html`` if it is there, else a fresh build."""
    if (BUILT / "index.html").exists():
        yield BUILT
        return
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html"]
        subprocess.run([*cmd, str(ROOT / "docs"), out], check=True, cwd=ROOT)
        yield Path(out)


@pytest.fixture(scope="module")
def base_url(site: Path) -> Iterator[str]:
    """The site served over HTTP on 127.0.0.1 (a file:// page would load differently)."""

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format: str, *args: Any) -> None:
            pass

    handler = functools.partial(Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


class Page:
    """One browser tab driven over the Chrome DevTools protocol (a websocket)."""

    def __init__(self, ws_url: str) -> None:
        import websocket

        # No Origin header: Chromium (from 111 on) refuses DevTools connections from an
        # origin it was not told to allow, and a client without one is no web page.
        self.ws = websocket.create_connection(ws_url, timeout=TIMEOUT, suppress_origin=True)
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def send(self, method: str, **params: Any) -> dict[str, Any]:
        """Call ``method`` and return its result; events that arrive meanwhile are kept."""
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv())
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                result: dict[str, Any] = message.get("result", {})
                return result
            self.events.append(message)

    def wait_for(self, event: str) -> None:
        """Read events until ``event`` arrives (or :data:`TIMEOUT` passes)."""
        deadline = time.monotonic() + TIMEOUT
        while not any(e.get("method") == event for e in self.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no {event} within {TIMEOUT} s")
            self.events.append(json.loads(self.ws.recv()))

    def errors(self) -> list[str]:
        """What the page logged as an error, one line each."""
        found = []
        for e in self.events:
            method, params = e.get("method"), e.get("params", {})
            if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                args = [str(a.get("value", a.get("description", ""))) for a in params["args"]]
                found.append("console: " + " ".join(args))
            elif method == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                found.append(
                    "exception: " + details.get("exception", {}).get("description", str(details))
                )
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                entry = params["entry"]
                found.append(f"log: {entry['text']} {entry.get('url', '')}".strip())
        return found

    def close(self) -> None:
        self.ws.close()


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A headless Chromium; yields its DevTools HTTP endpoint."""
    binary = chromium()
    if binary is None:
        pytest.skip(
            "Chromium is not installed (Debian: apt-get install chromium), so the built docs "
            "site is not checked in a browser"
        )
    pytest.importorskip("websocket", reason="websocket-client (the [docs] extra) is missing")
    profile = tmp_path_factory.mktemp("chromium-profile")
    args = [
        binary,
        "--headless=new",
        "--no-sandbox",  # root in a container has no user namespace for the sandbox
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--no-first-run",
        "--remote-debugging-address=127.0.0.1",
        "--remote-debugging-port=0",
        f"--user-data-dir={profile}",
        "about:blank",
    ]
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + TIMEOUT
        while not (port_file.exists() and port_file.read_text().strip()):
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"Chromium did not start (exit code {process.poll()})")
            time.sleep(0.1)
        yield f"http://127.0.0.1:{port_file.read_text().split()[0]}"
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()


def load(browser: str, url: str) -> tuple[list[dict[str, Any]], list[str]]:
    """Load ``url`` in a new tab: its images (src, complete, width) and its errors."""
    request = urllib.request.Request(f"{browser}/json/new?about:blank", method="PUT")
    with urllib.request.urlopen(request, timeout=TIMEOUT) as response:
        target = json.load(response)
    page = Page(target["webSocketDebuggerUrl"])
    try:
        for domain in ("Page", "Runtime", "Log", "Network"):
            page.send(f"{domain}.enable")
        page.send("Network.setCacheDisabled", cacheDisabled=True)  # every load from the site
        page.send("Page.navigate", url=url)
        page.wait_for("Page.loadEventFired")
        result = page.send(
            "Runtime.evaluate", expression=IMAGES_JS, awaitPromise=True, returnByValue=True
        )
        value: dict[str, Any] = result["result"]["value"]
        # MathJax shows a formula it cannot typeset as an error box, not on the console
        errors = [f"mathjax: {text}" for text in value["mathErrors"]]
        return value["images"], page.errors() + errors
    finally:
        page.close()
        with urllib.request.urlopen(f"{browser}/json/close/{target['id']}", timeout=TIMEOUT):
            pass


def assert_page_loads(browser: str, url: str) -> list[dict[str, Any]]:
    images, errors = load(browser, url)
    assert not errors, f"{url} logged errors: {errors}"
    broken = [i["src"] for i in images if not (i["complete"] and i["width"] > 0)]
    assert not broken, f"{url}: images that did not load: {broken}"
    return images


ENV_IDS = sorted({**ENV_SPECS, **HARDWARE_ENV_SPECS})


def test_the_index_loads_with_every_image(browser: str, base_url: str) -> None:
    images = assert_page_loads(browser, f"{base_url}/index.html")
    assert any(i["src"].endswith("pen_hand_front.png") for i in images)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_page_loads_with_its_picture(browser: str, base_url: str, env_id: str) -> None:
    images = assert_page_loads(browser, f"{base_url}/envs/{env_id}.html")
    assert any(i["src"].endswith(f"/{env_id}.png") for i in images), images


@pytest.mark.parametrize("page", ["grasp-model.html", "control-law.html"])
def test_the_equations_typeset_with_the_local_mathjax(
    browser: str, base_url: str, page: str
) -> None:
    assert_page_loads(browser, f"{base_url}/{page}")


def test_a_missing_image_fails_the_check(browser: str, base_url: str, site: Path) -> None:
    """The check can fail: the same env page with its picture gone."""
    picture = site / "_images" / "IAS-PenSlide-v0.png"
    if not picture.exists():
        pytest.fail(f"{picture} is not where the env page's picture is built")
    kept = picture.read_bytes()
    try:
        os.remove(picture)
        images, errors = load(browser, f"{base_url}/envs/IAS-PenSlide-v0.html")
    finally:
        picture.write_bytes(kept)
    assert any(not i["width"] for i in images if i["src"].endswith("/IAS-PenSlide-v0.png"))
    assert any("404" in e or "Failed to load" in e for e in errors), errors
