"""``studies.scripts.cert_by_environment``: members grouped by the GNSS environment they drew, means by closed form."""

from __future__ import annotations

import json

from mcap.writer import Writer

from studies.scripts.cert_by_environment import by_environment, main


def _campaign(tmp_path, members):
    with (tmp_path / "campaign.mcap").open("wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("member", "jsonschema", b"{}")
        cid = w.register_channel("/campaign/members", "json", sid)
        w.register_channel("/campaign/other", "json", sid)
        for i, m in enumerate(members):
            w.add_message(cid, log_time=i, publish_time=i, data=json.dumps(m).encode())
        w.finish()
    return tmp_path


def _m(i, env, vel, pos, ok=True):
    nees = {"attitude": 1.0, "heading": 0.5, "velocity": vel, "position": pos}
    return {"index": i, "seed": 300 + i, "ok": ok, "envelope": {"sensors.gnss.environment": env} if env else {},
            "nees_mean": nees}


def test_groups_and_means(tmp_path, capsys):
    d = _campaign(tmp_path, [_m(1, "urban_canyon", 2.0, 4.0), _m(0, "urban_canyon", 4.0, 2.0),
                             _m(2, "open_sky", 3.0, 3.0), _m(3, None, 1.0, 1.0),
                             _m(4, "open_sky", 99.0, 99.0, ok=False)])
    res = by_environment(d)
    assert set(res) == {"urban_canyon", "open_sky", "field"}
    assert res["urban_canyon"]["runs"] == 2 and res["urban_canyon"]["velocity"] == 3.0
    assert res["urban_canyon"]["worst_velocity"] == 4.0 and res["urban_canyon"]["worst_position"] == 4.0
    assert res["open_sky"]["runs"] == 1 and res["open_sky"]["position"] == 3.0  # the failed member is left out
    assert main([str(d)]) == 0
    assert "| urban_canyon | 2 | 1.00 | 0.50 | 3.00 | 3.00 | 4.00 | 4.00 |" in capsys.readouterr().out
