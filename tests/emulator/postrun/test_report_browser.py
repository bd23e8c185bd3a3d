"""report.html as a person sees it: rendered by headless Chromium, every figure present, loaded and not blank."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from tests.conftest import ROOT

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")

EXPECTED = ["Trajectory map", "Attitude and heading against truth", "Attitude error", "Velocity error",
            "Position error", "Filter consistency (NEES)", "Mode timeline", "Error CDF", "GNSS", "PSNS and sky",
            "Solar vector against truth", "DSP load over time", "DSP load per task"]

# on load, each figure is drawn onto a canvas and its non-white pixels counted; the result goes into the DOM
PROBE = """<script>
window.addEventListener('load', () => {
  const out = [];
  for (const img of document.querySelectorAll('img')) {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    let ink = 0;
    if (c.width && c.height) {
      const g = c.getContext('2d'); g.drawImage(img, 0, 0);
      const d = g.getImageData(0, 0, c.width, c.height).data;
      for (let i = 0; i < d.length; i += 4) if (d[i] < 200 || d[i+1] < 200 || d[i+2] < 200) ink++;
    }
    const frac = (ink / Math.max(1, c.width * c.height)).toFixed(4);
    out.push(img.alt + '|' + img.naturalWidth + 'x' + img.naturalHeight + '|' + frac);
  }
  const pre = document.createElement('pre'); pre.id = 'probe'; pre.textContent = out.join('\\n');
  document.body.appendChild(pre);
});
</script>"""


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium; .ci/run installs "
                                             "it as root)")
def test_report_renders_every_figure_non_empty_in_headless_chromium(tmp_path):
    from emulator.assembly.session import run_scenario
    from emulator.postrun.report import write_report
    from emulator.scenario.loader import load_scenario

    scn = load_scenario(ROOT / "scenarios" / "static_psns_camera.yaml", ["duration_s=6"])
    run_scenario(scn, tmp_path / "run")
    html = write_report(tmp_path / "run").read_text(encoding="utf-8")
    page = tmp_path / "probe.html"
    page.write_text(html.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    r = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files",
                        "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                       capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="probe">(.*?)</pre>', r.stdout, re.S)
    assert m, f"chromium rendered no probe output: {r.stderr[-2000:]}"
    rows = {alt: (size, float(ink)) for alt, size, ink in (ln.split("|") for ln in m.group(1).strip().splitlines())}
    assert list(rows) == EXPECTED
    for alt, (size, ink) in rows.items():
        w, h = (int(x) for x in size.split("x"))
        assert w > 200 and h > 100, f"{alt}: not loaded ({size})"
        assert ink > 0.01, f"{alt}: blank ({ink:.2%} ink)"
    assert "e+0" not in html.split("<img")[0]  # the tables print readable numbers


# installed first in <head>: every uncaught error, rejected promise, console.error / console.warn and image that
# fails to load is recorded, and the list is written into the DOM on load
ERROR_PROBE = """<script>
window.__errors = [];
window.addEventListener('error', e => window.__errors.push('error: ' + (e.message || (e.target && e.target.src)
  || 'resource')), true);
window.addEventListener('unhandledrejection', e => window.__errors.push('rejection: ' + e.reason));
for (const level of ['error', 'warn']) {
  const orig = console[level];
  console[level] = (...a) => { window.__errors.push('console.' + level + ': ' + a.join(' ')); orig.apply(console, a); };
}
window.addEventListener('load', () => {
  const pre = document.createElement('pre'); pre.id = 'errors';
  pre.textContent = 'checked\\n' + window.__errors.join('\\n');
  document.body.appendChild(pre);
});
</script>"""

#: the flags of issue 38: nothing fetched, nothing synchronised, no first-run UI
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium; .ci/run installs "
                                             "it as root)")
def test_fresh_run_report_renders_without_console_error_and_map_in_metres(tmp_path):
    """A fresh run of the GNSS-outage loop (shortened to 90 s, the outage 55-85 s inside it): the page renders in
    headless Chromium with no console error, a full-page screenshot is written (tmp_path/report.png), and the map
    is drawn in metres around the navigating track, not around lat = lon = 0."""
    from emulator.assembly.session import run_scenario
    from emulator.postrun.report import write_report
    from emulator.scenario.loader import load_scenario

    scn = load_scenario(ROOT / "scenarios" / "vehicle_loop_gnss_outage.yaml", ["duration_s=90", "expectations=[]"])
    run_scenario(scn, tmp_path / "run")
    report = write_report(tmp_path / "run")
    html = report.read_text(encoding="utf-8")
    assert "alt='Trajectory map'" in html
    page = tmp_path / "probe.html"
    page.write_text(html.replace("<head>", "<head>" + ERROR_PROBE, 1), encoding="utf-8")
    profile = tmp_path / "profile"
    r = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=5000",
                        "--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="errors">(.*?)</pre>', r.stdout, re.S)
    assert m, f"chromium rendered no probe output: {r.stderr[-2000:]}"
    lines = m.group(1).strip().splitlines()
    assert lines[0] == "checked" and lines[1:] == [], f"console errors: {lines[1:]}"
    shot = tmp_path / "report.png"
    r = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--screenshot={shot}",
                        "--window-size=1200,2400", "--hide-scrollbars", report.as_uri()],
                       capture_output=True, text=True, timeout=120)
    assert shot.exists() and shot.read_bytes().startswith(b"\x89PNG"), r.stderr[-2000:]
    assert shot.stat().st_size > 50_000  # a page of tables and figures, not a blank window


def test_map_spans_the_navigating_track_in_metres():
    """The map's data: frames before the coarse alignment (lat = lon = 0, mode ALIGNING only) are left out, so a
    static box's map spans metres, not the 10 000 km to (0, 0)."""
    import numpy as np

    import emulator.postrun.report as rep

    n = 400
    t = [0.01 * k for k in range(n)]
    pre = 100  # one second of frames at lat = lon = 0 before the alignment ends
    lat = [0.0] * pre + [39.979 + 1e-6 * np.sin(0.1 * k) for k in range(n - pre)]
    lon = [0.0] * pre + [116.339 + 1e-6 * np.cos(0.1 * k) for k in range(n - pre)]
    nav = {"time_s": t, "lat_deg": lat, "lon_deg": lon, "height_m": [50.0] * n,
           "mode": [1.0] * pre + [2.0 + 4.0] * (n - pre), "sig_pos_e_m": [2.0] * n, "sig_pos_n_m": [3.0] * n}
    truth = {"time_s": t, "lat_deg": [39.979] * n, "lon_deg": [116.339] * n, "height_m": [50.0] * n}
    captured = {}
    real_png = rep._png

    def keep(fig):
        ax = fig.axes[0]
        captured["xlim"], captured["ylim"] = ax.get_xlim(), ax.get_ylim()
        captured["patches"] = len(ax.patches)
        return real_png(fig)

    rep._png = keep
    try:
        assert [title for title, _ in rep._trajectory_figure(nav, truth, [])] == ["Trajectory map"]
    finally:
        rep._png = real_png
    span = max(captured["xlim"][1] - captured["xlim"][0], captured["ylim"][1] - captured["ylim"][0])
    assert 1.0 < span < 100.0  # metres: the 3 sigma ellipses (18 m across) and the 0.2 m wobble
    assert captured["patches"] == rep.MAP_ELLIPSES
