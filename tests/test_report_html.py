"""`rvte report`: the HTML shows the JSON's numbers, stands alone, says what changed, reads well.

One toy study (the RV-40E-121 with linear pins and bearings at 64 points, the
seed 002 fixed errors, 32 Monte Carlo reducers and a Sobol run of N = 16) is
run once into its default output folder; every test reports on it or on a copy
of it.  The browser test drives Debian's `chromium` over the DevTools protocol
on a pipe (--remote-debugging-pipe: JSON messages ending in a NUL byte on file
descriptors 3 and 4), which needs no Python package.
"""

import base64
import fcntl
import html
import json
import os
import re
import selectors
import shutil
import subprocess
import tempfile
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from tolerance_toy import write_study

import tolerance
from rvfmu.cli import main
from rvfmu.core.base.checks import InputError
from tolerance import report, run_mc, run_sobol
from tolerance.summaries import order_text

ROOT = Path(__file__).resolve().parent.parent
LAPTOP = (1366, 768)  # CSS pixels of the browser window the report must read well in

ALLOCATION = {
    "study": "toy",
    "study_file": "toy.toml",
    "allocated_study_file": "toy_allocated.toml",
    "target_yield": 0.9,
    "feasible": True,
    "factors": [
        {
            "name": "crank_cam_eccentricity.position_um",
            "unit": "um",
            "current": 9.0,
            "allocated": 11.2,
            "lower": 2.0,
            "upper": 30.0,
            "cost_current": 1.0,
            "cost_allocated": 0.8,
            "binding": "none",
        },
        {
            "name": "pin_radial.band_um",
            "unit": "um",
            "current": 5.0,
            "allocated": 2.0,
            "lower": 2.0,
            "upper": 20.0,
            "cost_current": 1.5,
            "cost_allocated": 2.25,
            "binding": "lower",
        },
    ],
    "total_cost": {"current": 2.5, "allocated": 3.05},
    "yield": {
        "current": {"estimate": 0.71875, "low": 0.546, "high": 0.844, "n": 32},
        "allocated": {"estimate": 0.9123, "low": 0.883, "high": 0.935, "n": 4096},
    },
    "surrogate": {"kind": "gaussian process", "samples": 256, "validation": "R2 0.97 on 64 held out"},
    "model_evaluations": 320,
}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The toy study file and its output folder (the default one: toy/output beside the file)."""
    folder = tmp_path_factory.mktemp("report")
    path = write_study(
        folder,
        study={"errors": str(ROOT / "studies" / "seed002_errors.toml")},
        spec={"te_pp_arcsec": 40.0, "rms_arcsec": 9.0},
    )
    run_mc(path, plots=False)
    run_sobol(path, plots=False)
    return path, folder / "toy" / "output"


@pytest.fixture(scope="module")
def written(study):
    path, out = study
    return report(out)


class Cells(HTMLParser):
    """Every <td> of a page: (data-src, data-key, data-scale, text); the banners above the contents
    (level, text); the images' sources and every src and href."""

    def __init__(self, text):
        super().__init__()
        self.cells, self.banners, self.images, self.links = [], [], [], []
        self._cell = self._banner = None
        self._nav = False
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "td":
            key = attrs.get("data-key")
            self._cell = [
                attrs.get("data-src"),
                None if key is None else json.loads(key),
                float(attrs.get("data-scale", 1)),
                "",
            ]
        elif tag == "div" and "banner" in attrs.get("class", "") and not self._nav:
            self._banner = [attrs["class"].split()[1], ""]
        elif tag == "nav":
            self._nav = True
        elif tag == "img":
            self.images.append(attrs["src"])
        for name in ("src", "href"):
            if name in attrs:
                self.links.append(attrs[name])

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self.cells.append(tuple(self._cell))
            self._cell = None
        elif tag == "div" and self._banner is not None:
            self.banners.append(tuple(self._banner))
            self._banner = None

    def handle_data(self, data):
        for item in (self._cell, self._banner):
            if item is not None:
                item[-1] += data


def shown_equals(text: str, value: float) -> bool:
    """True if `text` is `value` rounded to the digits it shows (fixed or e-notation)."""
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2])
    unit = 10.0 ** (int(exponent or 0) - decimals)
    return abs(float(text) - value) <= 0.5 * unit * (1 + 1e-9)


def check_round_trip(page: Cells, folder: Path) -> set:
    """Assert every cell that names its source shows that JSON value (times its scale), rounded
    to the digits shown; return the (file, key) pairs shown."""
    documents, seen = {}, set()
    for src, key, scale, text in page.cells:
        if src is None:
            continue
        value = documents.setdefault(src, json.loads((folder / src).read_text()))
        for k in key:
            value = value[k]
        assert shown_equals(text, value * scale), (src, key, text, value)
        seen.add((src, tuple(key)))
    return seen


def test_the_html_tables_show_the_numbers_of_the_json_outputs(study, written):
    path, out = study
    page = Cells(written.html.read_text())
    seen = check_round_trip(page, out)
    mc = json.loads((out / "mc_summary.json").read_text())
    for column, stats in mc["metrics"].items():
        for name in ("mean", "std", "min", "max"):
            assert ("mc_summary.json", ("metrics", column, name)) in seen
        for p in stats["percentiles"]:
            assert ("mc_summary.json", ("metrics", column, "percentiles", p)) in seen
    for i, _ in enumerate(mc["yields"]):
        for name in ("passed", "n", "fraction", "low", "high"):
            assert ("mc_summary.json", ("yields", i, name)) in seen
    sobol = json.loads((out / "sobol_indices.json").read_text())
    for column, entry in sobol["metrics"].items():
        for i, group in enumerate(entry["groups"]):
            for name in ("S1_reported", "S1_conf", "ST_reported", "ST_conf"):
                assert ("sobol_indices.json", ("metrics", column, "groups", i, name)) in seen
            for k, _ in enumerate(entry["convergence"]["n"]):
                assert (
                    "sobol_indices.json",
                    ("metrics", column, "convergence", "ST", group["name"], k),
                ) in seen
    # ... and the order of the ranks that sobol_indices.json holds, in the page and the summary
    markdown = written.markdown.read_text()
    for entry in sobol["metrics"].values():
        line = f"Order: {order_text(entry['order_groups'])}. Ranks joined by"
        assert line in written.html.read_text() and line in markdown
    # The Markdown summary shows the same numbers, in the same digits, and no figure.
    assert written.markdown == out / "report.md" and "data:image" not in markdown
    for src, key, _scale, text in page.cells:
        if src is not None:
            assert f"| {text} |" in markdown, (key, text)


def test_the_report_stands_alone_says_it_is_up_to_date_and_is_reproducible(study, written):
    path, out = study
    text = written.html.read_text()
    page = Cells(text)
    assert "<script" not in text.lower()
    assert all(link.startswith(("data:", "#")) for link in page.links), [
        link[:40] for link in page.links if not link.startswith(("data:", "#"))
    ]
    assert len(page.images) >= 4  # nominal TE, distributions, Sobol bars, convergence
    # the toy study's 64 points alias the pin-passing order: the nominal figure does not
    assert (
        "at 12480 points per revolution (resolving the pin-passing order; the study's "
        "metrics use its 64)" in html.unescape(text)
    )
    for src in page.images:
        assert base64.b64decode(src.partition(",")[2])[:8] == b"\x89PNG\r\n\x1a\n"
    assert page.banners[0][0] == "ok" and str(path) in page.banners[0][1]
    summary = written.to_json()
    assert summary["status"] == "up to date" and summary["study_file"] == str(path)
    assert summary["nominal"]["errors"].startswith("with the study's fixed errors")
    for needle in (
        "seed002_errors.toml",
        "Fixed errors",
        "inputs hash",
        json.loads((out / "manifest.json").read_text())["model_hash"],
        "SALib",
    ):
        assert needle in text
    errors_file = (ROOT / "studies" / "seed002_errors.toml").read_text()
    assert errors_file in html.unescape(text)  # the error file as written (escaped)
    # the software that computed the results, as recorded when the store was made, and now
    recorded = json.loads((out / "manifest.json").read_text())["versions"]
    assert recorded["numpy"] == np.__version__ and "python" in recorded
    row = [cell[-1] for cell in page.cells]
    at = row.index("numpy")
    assert row[at + 1 : at + 3] == [np.__version__, np.__version__]
    html_bytes, md_bytes = written.html.read_bytes(), written.markdown.read_bytes()
    again = report(out)
    assert again.html.read_bytes() == html_bytes and again.markdown.read_bytes() == md_bytes


def test_a_changed_study_file_or_model_is_said_at_the_top(study, tmp_path):
    path, out = study
    changed = tmp_path / "toy.toml"
    changed.write_text(path.read_text().replace("position_um = 8.0", "position_um = 6.0"))
    result = report(out, tmp_path / "changed.html", study_file=changed)
    page = Cells(result.html.read_text())
    level, text = page.banners[0]
    assert level == "bad" and "has changed since these results were computed" in text
    assert "differs in: tolerances" in text and "Monte Carlo" not in text
    assert result.summary["study_changed"] and result.summary["status"] == "study file changed"
    assert "has changed" in result.markdown.read_text().split("## Key results")[0]
    assert "Study file now" in result.html.read_text()
    # A copy of the folder, its manifest claiming another model, found with no study file.
    copy = tmp_path / "copy"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("report.*"))
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["model_hash"] = "0" * 64
    (copy / "manifest.json").write_text(json.dumps(manifest))
    result = report(copy)
    levels = [level for level, _ in Cells(result.html.read_text()).banners]
    assert levels == ["bad", "warn"] and result.summary["model_changed"]
    assert result.summary["study_changed"] is None and not result.summary["up_to_date"]
    assert "The model has changed" in result.summary["warnings"][0]
    # A spec edited since the Monte Carlo: nothing to recompute, but the yields are the old spec's.
    respec = tmp_path / "respec.toml"
    respec.write_text(path.read_text().replace("te_pp_arcsec = 40.0", "te_pp_arcsec = 35.0"))
    result = report(out, tmp_path / "respec.html", study_file=respec)
    assert [level for level, _ in Cells(result.html.read_text()).banners] == ["ok", "warn", "warn"]
    assert "te_pp_arcsec <= 35" in result.summary["warnings"][1]


def test_an_allocation_is_rendered_when_there_is_one(study, tmp_path):
    path, out = study
    copy = tmp_path / "output"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("report.*"))
    (copy / "allocation.json").write_text(json.dumps(ALLOCATION))
    result = report(copy, study_file=path)
    page = Cells(result.html.read_text())
    seen = check_round_trip(page, copy)
    for i, _ in enumerate(ALLOCATION["factors"]):
        for name in ("current", "allocated", "lower", "upper", "cost_current", "cost_allocated"):
            assert ("allocation.json", ("factors", i, name)) in seen
    for state in ("current", "allocated"):
        assert ("allocation.json", ("total_cost", state)) in seen
        for name in ("estimate", "low", "high", "n"):
            assert ("allocation.json", ("yield", state, name)) in seen
    assert "Tolerance allocation" in result.markdown.read_text()
    assert result.summary["allocation"]["feasible"] is True
    assert "Tolerance allocation" not in report(out).html.read_text()
    broken = json.loads(json.dumps(ALLOCATION))
    broken["factors"][1]["binding"] = "both"
    (copy / "allocation.json").write_text(json.dumps(broken))
    with pytest.raises(
        InputError,
        match=r"factors\[1\]\.binding = 'both': must be one of none, "
        "lower, upper",
    ):
        report(copy)


def test_the_command_prints_a_summary_and_refuses_bad_paths_at_once(study, tmp_path, capsys):
    path, out = study
    target = tmp_path / "supplier.html"
    assert main(["report", str(out), "-o", str(target), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["html"] == str(target) and printed["markdown"] == str(tmp_path / "supplier.md")
    assert target.is_file() and printed["mc"]["yields"][-1]["limit"] == "all limits"
    for argv, message in (
        ([str(tmp_path / "nowhere")], "output_dir = '.*nowhere': must be an existing study output folder"),
        ([str(tmp_path)], "output_dir = '.*': is not a study output folder: it has no manifest.json"),
        (
            [str(out), "-o", str(tmp_path / "r.pdf")],
            r"html = '.*r.pdf': must end in one of "
            r"\.html, \.htm",
        ),
        (
            [str(out), "-o", str(tmp_path / "no" / "r.html")],
            "html = .*: cannot be written: the folder .* does not exist",
        ),
        (
            [str(out), "--markdown", str(tmp_path / "r.txt")],
            r"markdown = .*: must end in one "
            r"of \.md",
        ),
        (
            [str(out), "--study", str(tmp_path / "none.toml")],
            "study = .*: must be a readable study TOML file",
        ),
    ):
        clock = time.perf_counter()
        assert main(["report", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and re.match(f"rvte report: error: {message}", err), err
        assert time.perf_counter() - clock < 2.0  # refused before any work


def test_tolerance_report_is_the_report_job():
    from tolerance.html_report import report as job

    assert tolerance.report is job


# -- in a real browser -------------------------------------------------------------------------


class Chromium:
    """Headless Chromium over the DevTools protocol on a pipe; `send` waits for its answer."""

    def __init__(self, executable: str, timeout: float = 60.0):
        self.timeout, self.events, self._id, self._buffer = timeout, [], 0, b""
        # Chromium reads fd 3 and writes fd 4; its ends are moved above 9 first, so that the
        # redirections to 3 and 4 cannot overwrite one another (bash: dash takes one digit only).
        theirs_in, self._out = os.pipe()
        self._in, theirs_out = os.pipe()
        for fd in (theirs_in, theirs_out):
            high = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
            os.close(fd)
            theirs_in, theirs_out = (high, theirs_out) if fd == theirs_in else (theirs_in, high)
        self._profile = tempfile.TemporaryDirectory()
        flags = [
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--remote-debugging-pipe",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-extensions",
            "--hide-scrollbars",
            f"--user-data-dir={self._profile.name}",
        ]
        self.process = subprocess.Popen(
            ["bash", "-c", f'exec "$0" "$@" 3<&{theirs_in} 4>&{theirs_out}', executable, *flags],
            pass_fds=(theirs_in, theirs_out),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(theirs_in)
        os.close(theirs_out)

    def send(self, method, session=None, **params):
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self._out, json.dumps(message).encode() + b"\0")
        while True:
            reply = self._next()
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            self.events.append(reply)

    def wait_for(self, method):
        while not any(e.get("method") == method for e in self.events):
            self.events.append(self._next())

    def _next(self):
        deadline = time.monotonic() + self.timeout
        with selectors.DefaultSelector() as selector:
            selector.register(self._in, selectors.EVENT_READ)
            while b"\0" not in self._buffer:
                if not selector.select(max(0.0, deadline - time.monotonic())):
                    raise TimeoutError("Chromium did not answer")
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise RuntimeError("Chromium closed its DevTools pipe")
                self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def close(self):
        try:
            self.send("Browser.close")
            self.process.wait(10)
        except (RuntimeError, TimeoutError, OSError, subprocess.TimeoutExpired):
            self.process.kill()
            self.process.wait()
        os.close(self._out)
        os.close(self._in)
        self._profile.cleanup()


@pytest.mark.skipif(
    shutil.which("chromium") is None,
    reason="Debian's chromium is not installed (apt-get install -y chromium)",
)
def test_the_report_reads_well_in_chromium_at_laptop_width(written, tmp_path):
    browser = Chromium(shutil.which("chromium"))
    try:
        target = browser.send("Target.createTarget", url="about:blank")["targetId"]
        tab = browser.send("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            browser.send(f"{domain}.enable", tab)
        width, height = LAPTOP
        browser.send(
            "Emulation.setDeviceMetricsOverride",
            tab,
            width=width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )
        browser.send("Page.navigate", tab, url=written.html.resolve().as_uri())
        browser.wait_for("Page.loadEventFired")
        page = browser.send(
            "Runtime.evaluate",
            tab,
            returnByValue=True,
            expression="""({
            images: [...document.images].map(i => [i.complete, i.naturalWidth, i.width]),
            scrollWidth: document.documentElement.scrollWidth,
            height: document.documentElement.scrollHeight,
            banner: document.querySelector('.banner').getBoundingClientRect().top})""",
        )
        page = page["result"]["value"]
        shot = browser.send("Page.captureScreenshot", tab, format="png")
        full = browser.send(
            "Page.captureScreenshot",
            tab,
            format="png",
            captureBeyondViewport=True,
            clip={"x": 0, "y": 0, "width": width, "height": page["height"], "scale": 1},
        )
    finally:
        browser.close()
    errors = [
        e["params"]
        for e in browser.events
        if (e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] == "error")
        or e.get("method") == "Runtime.exceptionThrown"
        or (e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error")
    ]
    assert errors == []
    requests = [
        e["params"]["request"]["url"]
        for e in browser.events
        if e.get("method") == "Network.requestWillBeSent"
    ]
    assert all(url.startswith(("file:", "data:")) for url in requests), requests
    assert len(page["images"]) >= 4
    assert all(done and natural > 0 and 0 < shown <= width for done, natural, shown in page["images"])
    assert page["scrollWidth"] <= width  # nothing wider than the window
    assert page["banner"] < height / 2  # the status is on the first screen
    for name, data in (("report-top.png", shot), ("report-full.png", full)):
        png = base64.b64decode(data["data"])
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
        (tmp_path / name).write_bytes(png)
        if os.environ.get("RVTE_SCREENSHOTS"):  # a folder to keep them in, to look at
            shutil.copy(tmp_path / name, Path(os.environ["RVTE_SCREENSHOTS"]) / name)
