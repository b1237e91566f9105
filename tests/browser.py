"""A real browser for the HTML pages the tool writes: headless Chromium (Debian's `chromium`).

`page_in_browser(path)` loads the page in Chromium inside a same-folder wrapper page whose script
reads the loaded document (title, sections, tables, and whether every image decoded to a picture
with a size) and writes it into the wrapper's DOM, which Chromium prints with --dump-dom.
`screenshot(path, png)` renders the page to a PNG. `make test` installs Chromium when it is missing
(see the Makefile), so these checks never skip.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--no-first-run",
    "--allow-file-access-from-files",
)
PROBE = """<!DOCTYPE html><html><body><pre id="result">pending</pre>
<iframe id="page" src="{src}" width="1300" height="900"></iframe>
<script>
document.getElementById("page").addEventListener("load", () => {{
  const d = document.getElementById("page").contentDocument;
  const images = [...d.images];
  document.getElementById("result").textContent = JSON.stringify({{
    title: d.title,
    sections: [...d.querySelectorAll("h2")].map(h => h.textContent),
    tables: d.querySelectorAll("table").length,
    images: images.length,
    images_drawn: images.filter(i => i.complete && i.naturalWidth > 0 && i.naturalHeight > 0).length,
    text_chars: d.body.innerText.length,
  }});
}});
</script></body></html>"""


@dataclass(frozen=True)
class PageInBrowser:
    """What Chromium saw of a page after loading it."""

    title: str
    sections: list[str]
    tables: int
    images: int
    images_drawn: int
    text_chars: int


def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        raise RuntimeError("chromium is not installed: `make test` installs it (apt-get install chromium)")
    return path


def _run(args: list[str], user_dir: str) -> str:
    done = subprocess.run(
        [chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={user_dir}", *args], capture_output=True, text=True, timeout=120
    )
    if done.returncode != 0:
        raise RuntimeError(f"chromium failed ({done.returncode}): {done.stderr.strip()[-500:]}")
    return done.stdout


def page_in_browser(page: Path) -> PageInBrowser:
    page = Path(page).resolve()
    with tempfile.TemporaryDirectory() as user_dir:
        probe = page.parent / f".browser-probe-{page.stem}.html"
        probe.write_text(PROBE.format(src=page.name), encoding="utf-8")
        try:
            dom = _run(["--virtual-time-budget=20000", "--dump-dom", probe.as_uri()], user_dir)
        finally:
            probe.unlink()
    found = re.search(r'<pre id="result">(.*?)</pre>', dom, re.S)
    if found is None or found.group(1) == "pending":
        raise AssertionError(f"the page did not finish loading in Chromium: {page}")
    return PageInBrowser(**json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&")))


def screenshot(page: Path, png: Path, width: int = 1300, height: int = 2000) -> Path:
    with tempfile.TemporaryDirectory() as user_dir:
        _run(
            [f"--window-size={width},{height}", f"--screenshot={Path(png).resolve()}", Path(page).resolve().as_uri()],
            user_dir,
        )
    return Path(png)
