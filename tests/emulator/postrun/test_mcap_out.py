"""run.mcap read back with the ``mcap`` library's reader (not the writer): every channel with its schema, messages in
time order, counts equal to nav.csv and the capture, values equal to nav.csv's text, the raw-bytes channels decoding
to the capture's frames; and the raw sensor tables against the frames decoded from the capture."""

from __future__ import annotations

import base64
import csv
import json
import math
from collections import Counter, defaultdict
from itertools import pairwise

import pytest
from mcap.reader import make_reader

from emulator.assembly.ports import port_formats
from emulator.assembly.session import run_scenario
from emulator.postrun.mcap_out import (
    FOXGLOVE_SCHEMAS,
    RAW_SCHEMA,
    TOPICS,
    aop_image,
    attitude_quaternion,
    write_run_mcap,
)
from emulator.postrun.sensor_tables import write_sensor_tables
from emulator.recording.capture import read_capture
from emulator.scenario import load_scenario
from protocols.imu_frame import ImuFrame
from protocols.nmea import Gga
from protocols.psns import PolarizationObs
from protocols.stream import StreamDecoder
from tests.conftest import ROOT, SCENARIOS


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 6.0
    d = tmp_path_factory.mktemp("mcap") / "run"
    run_scenario(scn, d)
    write_run_mcap(d)
    return d


@pytest.fixture(scope="module")
def mcap_read(run_dir):
    """(summary, [(channel topic, schema name, log_time, publish_time, message dict)]) in file order."""
    with open(run_dir / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        msgs = [(ch.topic, sc.name if sc is not None else None, m.log_time, m.publish_time, json.loads(m.data))
                for sc, ch, m in reader.iter_messages(log_time_order=False)]
    return summary, msgs


def _csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_every_channel_is_there_with_its_schema(mcap_read, run_dir):
    summary, _ = mcap_read
    assert summary is not None
    schemas = summary.schemas
    by_topic = {ch.topic: schemas[ch.schema_id] for ch in summary.channels.values()}
    for topic, name in TOPICS.items():
        assert topic in by_topic, topic
        sc = by_topic[topic]
        assert sc.name == name and sc.encoding == "jsonschema"
        assert json.loads(sc.data)["title"] == name
        if name in FOXGLOVE_SCHEMAS:  # the well-known schema's required fields
            assert set(json.loads(sc.data)["required"]) == set(FOXGLOVE_SCHEMAS[name]["required"])
    _, recs = read_capture(run_dir / "capture.psnscap")
    for link, direction in {(r.link, r.direction) for r in recs}:
        assert by_topic[f"/raw/{link}/{direction}"].name == RAW_SCHEMA
    for ch in summary.channels.values():
        assert ch.message_encoding == "json"


def test_messages_are_time_ordered_on_the_scenario_clock(mcap_read, run_dir):
    _, msgs = mcap_read
    times = [m[2] for m in msgs]
    assert times == sorted(times)
    s = json.loads((run_dir / "summary.json").read_text())
    assert times[0] >= 0 and times[-1] <= round(s["sim_duration_s"] * 1e9)


def test_counts_equal_nav_csv_and_the_capture(mcap_read, run_dir):
    _, msgs = mcap_read
    n = Counter(m[0] for m in msgs)
    cols, nav = _csv(run_dir / "nav.csv")
    _, truth = _csv(run_dir / "truth.csv")
    assert len(nav) > 500
    for topic in ("/nav/solution", "/nav/location", "/nav/pose", "/nav/error"):
        assert n[topic] == len(nav)
    modes = [int(r[cols.index("mode")]) for r in nav]
    assert n["/nav/mode"] == 1 + sum(a != b for a, b in pairwise(modes)) >= 2  # aligning, then navigating
    assert n["/truth/state"] == n["/truth/location"] == len(truth)
    assert n["/tf"] == len(nav) + len(truth)
    _, recs = read_capture(run_dir / "capture.psnscap")
    per_link = Counter(f"/raw/{r.link}/{r.direction}" for r in recs)
    assert {t: c for t, c in n.items() if t.startswith("/raw/")} == per_link
    _, psns = _csv(run_dir / "psns.csv")
    assert n["/psns/solar_vector"] == len(psns) > 0
    s = json.loads((run_dir / "summary.json").read_text())
    assert n["/expectations"] == len(s["expectations"])
    lines = (run_dir / "events.jsonl").read_text().splitlines()
    assert n["/events"] == sum(1 for line in lines if line.strip())


def test_values_equal_nav_csv_to_the_last_digit(mcap_read, run_dir):
    _, msgs = mcap_read
    cols, nav = _csv(run_dir / "nav.csv")
    sol = [m for m in msgs if m[0] == "/nav/solution"]
    loc = [m for m in msgs if m[0] == "/nav/location"]
    err = [m for m in msgs if m[0] == "/nav/error"]
    for row, (_, _, log_t, pub_t, m), lm, em in zip(nav, sol, loc, err, strict=True):
        for c, cell in zip(cols, row, strict=True):
            v = m[c]
            assert ("" if v is None else repr(v) if isinstance(v, float) else str(v)) == cell, c
        r = dict(zip(cols, row))
        assert log_t == round(float(r["time_s"]) * 1e9) and pub_t == round(float(r["arrival_s"]) * 1e9)
        fix = lm[4]
        assert (fix["latitude"], fix["longitude"], fix["altitude"]) == (float(r["lat_deg"]), float(r["lon_deg"]),
                                                                         float(r["height_m"]))
        cov = fix["position_covariance"]
        assert cov[0] == float(r["sig_pos_e_m"]) ** 2 and cov[4] == float(r["sig_pos_n_m"]) ** 2
        assert cov[8] == float(r["sig_pos_u_m"]) ** 2 and fix["position_covariance_type"] == 2
        e = em[4]
        assert e["err_pos_n_m"] == (float(r["err_pos_n_m"]) if r["err_pos_n_m"] else None)
        assert e["sig_att_u_deg"] == float(r["sig_att_u_deg"])
        assert e["sig3_att_u_deg"] == 3.0 * float(r["sig_att_u_deg"]) and e["sig3_pos_e_m"] == 3.0 * float(
            r["sig_pos_e_m"])  # the +-3 sigma bounds the layout's error plots draw


def test_raw_channels_decode_to_the_captures_frames(mcap_read, run_dir):
    _, msgs = mcap_read
    from_mcap: dict[tuple[str, str], bytearray] = defaultdict(bytearray)
    for topic, _, _, _, m in msgs:
        if topic.startswith("/raw/"):
            assert topic == f"/raw/{m['link']}/{m['direction']}"
            from_mcap[(m["link"], m["direction"])] += base64.b64decode(m["data"])
    _, recs = read_capture(run_dir / "capture.psnscap")
    from_cap: dict[tuple[str, str], bytearray] = defaultdict(bytearray)
    for r in recs:
        from_cap[(r.link, r.direction)] += r.data
    assert from_mcap == from_cap
    decoded = 0
    for (link, direction), data in from_cap.items():
        fm = port_formats(link).get(direction)
        if not fm:
            continue
        a = StreamDecoder(fm).feed(bytes(from_mcap[(link, direction)]))
        b = StreamDecoder(fm).feed(bytes(data))
        assert a == b
        decoded += len(a)
    assert decoded > 1000


def test_the_pose_quaternion_turns_forward_to_the_heading():
    """Closed form: the body's forward axis (y) in ENU is (sin h cos p, cos h cos p, sin p) for heading h (clockwise
    from North) and pitch p, whatever the roll; the quaternion is unit."""
    for roll, pitch, heading in ((0.0, 0.0, 0.0), (10.0, -20.0, 30.0), (-170.0, 80.0, 250.0), (5.0, 3.0, 181.0)):
        x, y, z, w = attitude_quaternion(roll, pitch, heading)
        assert math.isclose(x * x + y * y + z * z + w * w, 1.0, rel_tol=1e-12)
        # rotate (0, 1, 0) by q: v' = v + 2 w (q x v) + 2 q x (q x v)
        v = (0.0, 1.0, 0.0)
        c1 = (y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0])
        c2 = (y * c1[2] - z * c1[1], z * c1[0] - x * c1[2], x * c1[1] - y * c1[0])
        out = [v[i] + 2 * w * c1[i] + 2 * c2[i] for i in range(3)]
        h, p = math.radians(heading), math.radians(pitch)
        assert out == pytest.approx([math.sin(h) * math.cos(p), math.cos(h) * math.cos(p), math.sin(p)], abs=1e-12)


def test_sensor_tables_rows_equal_the_frames_in_the_capture(run_dir):
    counts = write_sensor_tables(run_dir)
    _, recs = read_capture(run_dir / "capture.psnscap")
    dec = {"uart1": StreamDecoder(port_formats("uart1")["in"]), "gnss": StreamDecoder(port_formats("gnss")["in"]),
           "psns": StreamDecoder(port_formats("psns")["in"])}
    frames: dict[str, list] = defaultdict(list)
    for r in recs:
        if r.link in dec and r.direction == "in":
            frames[r.link] += dec[r.link].feed(r.data)
    imu = [f for f in frames["uart1"] if isinstance(f, ImuFrame)]
    gga = [f for f in frames["gnss"] if isinstance(f, Gga)]
    obs = [f for f in frames["psns"] if isinstance(f, PolarizationObs)]
    assert counts == {"imu.csv": len(imu), "gnss.csv": len(gga), "psns_frames.csv": len(obs)}
    assert len(imu) == pytest.approx(6.0 * 200, abs=2) and len(gga) >= 5 and len(obs) >= 29
    cols, rows = _csv(run_dir / "imu.csv")
    assert cols[5] == "gyro_x_dps" and cols[11] == "accel_x_g"
    assert [int(r[1]) for r in rows] == [f.seq for f in imu]
    # the box stands still and level: the z accelerometer reads about 1 g
    assert sum(float(r[13]) for r in rows[100:]) / len(rows[100:]) == pytest.approx(1.0, abs=0.01)
    cols, rows = _csv(run_dir / "gnss.csv")
    assert [float(r[cols.index("lat_deg")]) for r in rows] == [g.lat_deg for g in gga]


LAYOUT = ROOT / "docs" / "foxglove" / "psns-hil.layout.json"
#: the schema each panel kind expects of the topics it names
PANEL_SCHEMA = {"Map": "foxglove.LocationFix", "3D": "foxglove.PoseInFrame", "RosOut": "foxglove.Log",
                "Image": "foxglove.RawImage"}


def _panels(node):
    if isinstance(node, str):
        return [node]
    return _panels(node["first"]) + _panels(node["second"])


def test_the_shipped_foxglove_layout_names_only_what_the_mcap_has(mcap_read):
    """Every panel of docs/foxglove/psns-hil.layout.json is placed in the layout tree, and every topic, field and
    frame it names exists in a library run's MCAP with the schema its panel expects (the app is not at hand)."""
    summary, msgs = mcap_read
    layout = json.loads(LAYOUT.read_text(encoding="utf-8"))
    configs = layout["configById"]
    assert sorted(_panels(layout["layout"])) == sorted(configs)
    schema_of = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
    first = {}
    for topic, _, _, _, m in msgs:
        first.setdefault(topic, m)
    frames = {m["child_frame_id"] for t, _, _, _, m in msgs if t == "/tf"}
    checked = 0
    for panel_id, cfg in configs.items():
        kind = panel_id.split("!")[0]
        topics = list(cfg.get("topicColors", {})) + list(cfg.get("topics", {}))
        topics += [cfg[k] for k in ("topicToRender", "topicPath") if k in cfg]
        topics += [cfg["imageMode"]["imageTopic"]] if "imageMode" in cfg else []
        for topic in topics:
            assert schema_of.get(topic) == PANEL_SCHEMA.get(kind, schema_of.get(topic)), (panel_id, topic)
            assert topic in schema_of, (panel_id, topic)
            checked += 1
        for path in cfg.get("paths", []):
            topic, fld = path["value"].split(".", 1)
            fld, _, modifier = fld.partition(".@")  # a Foxglove math modifier (.@negative) on a numeric field
            assert topic in schema_of and fld in first[topic], (panel_id, path["value"])
            assert modifier in ("", "negative"), (panel_id, path["value"])
            checked += 1
        if "followTf" in cfg:
            assert cfg["followTf"] in frames
    assert checked >= 20


def test_the_aop_image_paints_each_point_with_its_angle(mcap_read):
    """aop_image: a point's own pixel carries its AoP (-90..90 deg -> 1..255), nothing observed stays 0; in the run's
    MCAP one image a second, the size of the IMX250MZR (2448 x 2048) binned by 16."""
    from protocols.psns import PolarizationPoint

    pts = [PolarizationPoint(x, y, aop, 30000, 5000) for x, y, aop in
           ((100, 100, -9000), (300, 100, 0), (100, 300, 9000), (300, 300, 4500))]
    w, h, img = aop_image(pts)
    assert (w, h) == (153, 128) and len(img) == w * h
    px = {(x, y): img[(y // 16) * w + x // 16] for x, y, _ in [(p.x_px, p.y_px, 0) for p in pts]}
    assert px == {(100, 100): 1, (300, 100): 128, (100, 300): 255, (300, 300): 191}  # 1 + round(190.5), half even
    assert img[(1000 // 16) * w + 1000 // 16] == 0
    _, msgs = mcap_read
    images = [(t, m) for topic, _, t, _, m in msgs if topic == "/psns/aop_image"]
    assert len(images) == 6
    assert all(m["width"] == 153 and m["height"] == 128 and m["encoding"] == "mono8" for _, m in images)
    assert all(len(base64.b64decode(m["data"])) == 153 * 128 for _, m in images)
    assert sum(base64.b64decode(images[0][1]["data"])) > 0
