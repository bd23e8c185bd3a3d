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
    from emulator.assembly.runner import run_scenario
    from emulator.recording.report import write_report
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
