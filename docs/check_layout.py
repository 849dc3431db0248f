"""Check the documentation site's layout in a real browser (headless Chromium).

Builds the site (or takes a built one), opens the landing page, a guide, the API reference and
the command-line reference at 1280 px wide, screenshots each into ``--shots`` and fails where a
code block is wider than its column (its text cut off or scrolled), where the content column
is narrower than ``--min-column`` px, or where the left sidebar is shown empty.

Usage (from the repository root; needs Debian's ``chromium`` package)::

    python docs/check_layout.py                       # builds into a temporary directory
    python docs/check_layout.py --html docs/_build/html --shots layout-shots

The measurement runs inside the page: a small script, injected into a copy of each page, reads
the DOM after load (``scrollWidth`` against ``clientWidth`` of every ``pre``, the column's
width) and writes a JSON report into the page, which ``chromium --dump-dom`` prints.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The pages looked at: the landing page, a guide, the API reference, the CLI reference.
PAGES = ("index.html", "guides/sample-loop.html", "api/observers.html", "api/cli.html")
WIDTH, HEIGHT = 1280, 1600
FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--hide-scrollbars", "--virtual-time-budget=5000",
)  # fmt: skip
MARK = "hpdob-layout-report"

PROBE = """
<script>
window.addEventListener("load", function () {
  var column = document.querySelector("article.bd-article") || document.querySelector("main");
  var right = column ? column.getBoundingClientRect().right : window.innerWidth;
  var blocks = [];
  document.querySelectorAll("pre").forEach(function (pre) {
    var box = pre.getBoundingClientRect();
    if (box.width === 0) { return; }
    if (pre.scrollWidth > pre.clientWidth + 1 || box.right > right + 1) {
      blocks.push({line: (pre.textContent.split("\\n").sort(function (a, b) {
                     return b.length - a.length; })[0] || "").slice(0, 100),
                   scrollWidth: pre.scrollWidth, clientWidth: pre.clientWidth});
    }
  });
  var sidebar = document.querySelector(".bd-sidebar-primary");
  var shown = sidebar && sidebar.getBoundingClientRect().width > 0 &&
              getComputedStyle(sidebar).display !== "none";
  var report = {
    column: column ? Math.round(column.getBoundingClientRect().width) : 0,
    overflow: blocks,
    emptySidebar: Boolean(shown &&
      sidebar.querySelectorAll(".sidebar-primary-items__start nav a").length === 0),
    firstHeading: (document.querySelector("article h2") || {}).textContent || ""
  };
  var out = document.createElement("pre");
  out.id = "MARK";
  out.textContent = JSON.stringify(report);
  document.body.appendChild(out);
});
</script>
""".replace("MARK", MARK)


def chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    sys.exit("check_layout: no chromium found (apt-get install -y chromium)")


def build(target: Path) -> Path:
    """Build the site like tests/test_docsite.py (from a copy of docs/ and examples/)."""
    ignore = shutil.ignore_patterns("_build", "api", "auto_examples", "__pycache__")
    shutil.copytree(ROOT / "docs", target / "docs", ignore=ignore)
    shutil.copytree(ROOT / "examples", target / "examples", ignore=ignore)
    html = target / "html"
    subprocess.run([sys.executable, "-m", "sphinx", "-q", "-b", "html", "-d",
                    str(target / "doctrees"), str(target / "docs"), str(html)],
                   check=True)  # fmt: skip
    return html


def run(browser: str, profile: Path, url: str, *extra: str) -> str:
    cmd = [browser, *FLAGS, f"--user-data-dir={profile}", f"--window-size={WIDTH},{HEIGHT}",
           *extra, url]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"chromium failed on {url}: {done.stderr[-500:]}")
    return done.stdout


def every_page(html: Path) -> tuple[str, ...]:
    """The site's own pages (the guides, topics, API and gallery pages; not search or index)."""
    skip = ("genindex", "search", "py-modindex", "_modules/", "_sources/", "_static/", "_probe_")
    pages = (str(p.relative_to(html)) for p in sorted(html.rglob("*.html")))
    return tuple(p for p in pages if not p.startswith(skip) and "/_probe_" not in p)


def check(html: Path, shots: Path, min_column: int, pages=PAGES) -> list[str]:
    """Screenshot and measure each page; return the problems found."""
    browser = chromium()
    problems = []
    shots.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="hpdob-layout-") as tmp:
        site = Path(tmp) / "site"
        shutil.copytree(html, site)  # the probe goes into copies, never into the built site
        for page in pages:
            path = site / page
            if not path.exists():
                problems.append(f"{page}: not in the built site")
                continue
            profile = Path(tmp) / f"profile-{len(problems)}-{page.replace('/', '-')}"
            shot = shots / (page.replace("/", "-").removesuffix(".html") + ".png")
            run(browser, profile, path.as_uri(), f"--screenshot={shot}")
            probed = path.with_name(f"_probe_{path.name}")
            probed.write_text(path.read_text().replace("</body>", PROBE + "</body>"))
            dom = run(browser, profile, probed.as_uri(), "--dump-dom")
            found = re.search(rf'<pre id="{MARK}"[^>]*>(.*?)</pre>', dom, flags=re.S)
            if not found:
                problems.append(f"{page}: the layout probe did not report")
                continue
            report = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&")
                                .replace("&lt;", "<").replace("&gt;", ">"))  # fmt: skip
            print(f"{page}: column {report['column']} px, {len(report['overflow'])} "
                  f"overflowing code blocks, first section {report['firstHeading']!r} "
                  f"-> {shot}")  # fmt: skip
            for block in report["overflow"]:
                problems.append(
                    f"{page}: a code block overflows its column ({block['scrollWidth']} > "
                    f"{block['clientWidth']} px): {block['line'].strip()!r}"
                )
            if report["column"] < min_column:
                problems.append(f"{page}: the content column is {report['column']} px wide "
                                f"(< {min_column} px at a {WIDTH} px window)")  # fmt: skip
            if report["emptySidebar"]:
                problems.append(f"{page}: the left sidebar is shown but empty")
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--html",
        type=Path,
        default=None,
        help="a built site (default: build one in a temporary directory)",
    )
    parser.add_argument(
        "--shots",
        type=Path,
        default=Path("layout-shots"),
        help="where the screenshots go (default: %(default)s)",
    )
    parser.add_argument(
        "--all", action="store_true", help="measure every page of the site, not only the four"
    )
    parser.add_argument(
        "--min-column",
        type=int,
        default=720,
        help="narrowest acceptable content column [px] (default: %(default)s)",
    )
    args = parser.parse_args(argv)  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="hpdob-site-") as tmp:
        html = args.html if args.html is not None else build(Path(tmp))
        pages = every_page(html) if args.all else PAGES
        problems = check(html, args.shots, args.min_column, pages)
    for problem in problems:
        print(f"FAIL {problem}")
    print("layout: ok" if not problems else f"layout: {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
