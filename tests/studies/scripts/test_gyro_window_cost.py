"""studies/scripts/gyro_window_cost.py: usage without a tree, and its child program is valid Python."""

from __future__ import annotations

from studies.scripts import gyro_window_cost


def test_without_the_other_tree_it_prints_its_usage_and_exits_2(capsys):
    assert gyro_window_cost.main([]) == 2
    assert "gyro_window_cost OTHER_TREE" in capsys.readouterr().err


def test_the_child_program_compiles_and_triggers_as_the_fpga_does():
    compile(gyro_window_cost._CHILD, "<child>", "exec")
    assert "k * period - period" in gyro_window_cost._CHILD  # t_prev = t - period (fpga.py), see the study
