"""``visnav reach`` refuses an unbounded SpaceEx horizon (``time-horizon = -1``) without ``--horizon``: a flowpipe is
bounded; with ``--horizon`` it runs over ``[0, H]`` only.  ``visnav verify`` proves the stable dwell cycle of
tests/analysis/reach/test_induction.py for all time (exit 0) and says how."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
BALL = ROOT / "tests" / "data" / "spaceex" / "spaceexparser" / "bball" / "bball.xml"
CFG = ('system = "system"\ninitially = "10<=x<=10.2 & v==0"\nforbidden = "x >= 10.5"\ntime-horizon = -1\n'
       'output-variables = "x,v"\n')


def test_reach_with_an_unbounded_horizon_exits_2_and_says_what_to_do(tmp_path, cli):
    cfg = tmp_path / "u.cfg"
    cfg.write_text(CFG)
    code, _, err = cli("reach", "--problem", BALL, "--config", cfg)
    assert code == 2 and "time-horizon < 0 is unbounded" in err and "--horizon" in err and "Traceback" not in err
    code, out, err = cli("reach", "--problem", BALL, "--config", cfg, "--horizon", "2", "--json")
    assert code in (0, 5) and "Traceback" not in err


def test_verify_proves_an_unbounded_property_by_cycle_induction(tmp_path, cli):
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "analysis" / "reach"))
    from test_induction import _files

    xml, cfg = _files(tmp_path)
    code, out, err = cli("verify", xml, "--config", cfg, "--budget", "2", "--out", tmp_path / "v")
    assert code == 0 and "PROVEN" in out and "cycle induction for all t >= 0 (re-checked)" in out, out + err
