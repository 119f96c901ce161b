"""The report opened in a real headless browser (Debian's chromium): rendered, no broken image."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from autopilot.cli import main
from autopilot.review.synthetic import write_synthetic_log
from tests.test_review_modes import write_daemon_log

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None)


def _need_chromium():
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed but CI is set: .ci/run must install it")
        pytest.skip("chromium not installed (apt-get install chromium); required in CI")


def _chromium(tmp_path, url: str, *mode: str) -> subprocess.CompletedProcess:
    args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            f"--user-data-dir={tmp_path / 'chromium-profile'}", "--window-size=1200,2000", *mode, url]
    try:
        return subprocess.run(args, capture_output=True, text=True, timeout=120, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:  # pragma: no cover - environment problem
        if os.environ.get("CI"):
            raise
        pytest.skip(f"chromium could not run here: {exc}")


def _image_check(tmp_path, html_path) -> tuple[int, int]:
    """(images, broken images) as marked by the report's inline script after the load event."""
    dom = _chromium(tmp_path, html_path.as_uri(), "--dump-dom").stdout
    m = re.search(r'<body[^>]*data-images="(\d+)"[^>]*data-broken-images="(\d+)"', dom)
    assert m, f"the image check did not run; chromium printed: {dom[:500]!r}"
    return int(m.group(1)), int(m.group(2))


@pytest.fixture(scope="module")
def reviewed(tmp_path_factory):
    d = tmp_path_factory.mktemp("browser")
    write_synthetic_log(d / "a.jsonl")
    write_synthetic_log(d / "b.jsonl", failsafe_at_s=25.0, weave_m=2.0)
    write_daemon_log(d).rename(d / "c.jsonl")  # modes, holds and a failing battery (issue 15)
    out = d / "out"
    assert main(["review", *(str(d / f"{k}.jsonl") for k in "abc"), "--out", str(out)]) == 0
    return d, out


def test_screenshot_is_not_blank(reviewed, tmp_path):
    _need_chromium()
    _, out = reviewed
    shot = tmp_path / "shot.png"
    proc = _chromium(tmp_path, (out / "report.html").as_uri(), f"--screenshot={shot}")
    assert shot.exists(), proc.stderr[-2000:]
    import matplotlib.image

    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[:2] == (2000, 1200)
    gray = pixels[..., :3].mean(axis=2)
    assert gray.std() > 0.05  # a white or single-colour page has ~0
    assert np.mean(gray < 0.5) > 0.005  # some dark ink: text, lines


@pytest.mark.parametrize("page", ["report.html", "1-a/report.html", "2-b/report.html", "3-c/report.html"])
def test_no_broken_images(reviewed, tmp_path, page):
    _need_chromium()
    _, out = reviewed
    images, broken = _image_check(tmp_path, out / page)
    assert images >= 1 and broken == 0
    if page != "report.html":  # every figure, the battery panel among them, is on the page and loaded
        html = (out / page).read_text()
        assert images == html.count("<img ") and 'src="battery.png"' in html


def test_the_check_sees_a_broken_image(reviewed, tmp_path):
    _need_chromium()
    _, out = reviewed
    page = (out / "report.html").read_text().replace('src="tracks.png"', 'src="missing.png"')
    bad = out / "broken.html"
    bad.write_text(page)
    assert _image_check(tmp_path, bad) == (1, 1)


def test_a_campaign_report_renders_with_every_figure(tmp_path):
    """The campaign's report.html (figures inline as data URIs) in the same browser: every figure decodes."""
    _need_chromium()
    from pathlib import Path

    spec = Path(__file__).resolve().parents[1] / "config" / "campaigns" / "pond-robustness.yaml"
    out = tmp_path / "campaign"
    assert main(["campaign", str(spec), "--runs", "24", "--jobs", "1", "--out", str(out), "--quiet"]) == 0
    images, broken = _image_check(tmp_path, out / "report.html")
    assert images >= 3 and broken == 0, (images, broken)
