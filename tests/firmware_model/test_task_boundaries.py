"""The firmware as a composition of task objects (issue 42 item 3): each extracted task owns its state, and no
code reads another task's attributes.

Checked on the source (AST), so a breach fails whatever the run does:

* neither ``Firmware`` (the cyclic executive) nor a task object's class has a base class (its MRO is the class and
  ``object``): no mixins;
* every ``self.X`` a task class reads is its own: assigned in the class or defined by it (a method, a property);
  what it uses of the others it receives as collaborators in its constructor;
* nobody (the executive, the other tasks) reaches into a task object's private state: ``<something>.<task>._X``
  does not occur outside the task's own class, only its public methods (and the navigation core's ``nav`` and
  ``filter``) are used.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import firmware_model
from firmware_model.firmware import Firmware
from firmware_model.tasks.alignment import AlignmentTask
from firmware_model.tasks.gnss import GnssTask
from firmware_model.tasks.host import HostTask
from firmware_model.tasks.navigation import NavCore
from firmware_model.tasks.output import OutputTask
from firmware_model.tasks.psns import PsnsTask
from firmware_model.tasks.timekeeping import Clock

PKG = Path(firmware_model.__file__).parent
#: the task objects: (class, the attribute of the executive that holds it)
TASKS = [(Clock, "clock"), (GnssTask, "gnss"), (NavCore, "core"), (OutputTask, "output"),
         (PsnsTask, "psns"), (AlignmentTask, "alignment"), (HostTask, "host")]


def _class_node(cls: type) -> ast.ClassDef:
    tree = ast.parse(Path(inspect.getfile(cls)).read_text())
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == cls.__name__:
            return node
    raise AssertionError(f"class {cls.__name__} not found in its module")


def _owned(node: ast.ClassDef) -> set[str]:
    """Attributes a class owns: its methods and class-level names, and every ``self.X`` it assigns."""
    own = set()
    for item in node.body:
        if isinstance(item, ast.FunctionDef | ast.AsyncFunctionDef):
            own.add(item.name)
        elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
            own.add(item.target.id)
        elif isinstance(item, ast.Assign):
            own.update(t.id for t in item.targets if isinstance(t, ast.Name))
    for sub in ast.walk(node):
        targets: list[ast.expr] = []
        if isinstance(sub, ast.Assign):
            targets = list(sub.targets)
        elif isinstance(sub, ast.AnnAssign | ast.AugAssign):
            targets = [sub.target]
        for t in targets:
            for e in ast.walk(t):
                if isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name) and e.value.id == "self":
                    own.add(e.attr)
    return own


@pytest.mark.parametrize(("cls", "attr"), TASKS, ids=[c.__name__ for c, _ in TASKS])
def test_a_task_object_has_no_base_and_reads_only_its_own_state(cls: type, attr: str) -> None:
    assert cls.__mro__ == (cls, object)
    node = _class_node(cls)
    own = _owned(node)
    foreign = sorted({f"self.{e.attr} (line {e.lineno})" for e in ast.walk(node)
                      if isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name) and e.value.id == "self"
                      and e.attr not in own})
    assert not foreign, f"{cls.__name__} reads attributes it does not own: {foreign}"


def test_nobody_reads_a_task_objects_private_state() -> None:
    task_attrs = {attr for _, attr in TASKS}
    breaches = []
    for path in sorted(PKG.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for e in ast.walk(tree):
            # <x>.<task>._private (the executive and the mixins: self.clock._t_last_us)
            if (isinstance(e, ast.Attribute) and e.attr.startswith("_") and not e.attr.startswith("__")
                    and isinstance(e.value, ast.Attribute) and e.value.attr in task_attrs):
                breaches.append(f"{path.relative_to(PKG)}:{e.lineno}: .{e.value.attr}.{e.attr}")
    assert not breaches, "private state of a task object read from outside it: " + ", ".join(breaches)


def test_the_executive_has_no_mixin_base_and_holds_every_task() -> None:
    """Issue 42 item 3's done-when: ``Firmware``'s MRO is the class and ``object``; each task is an object it holds,
    and the tasks share one navigation core, one clock and one status record (explicit collaborators)."""
    assert Firmware.__mro__ == (Firmware, object)
    fw = Firmware()
    for cls, attr in TASKS:
        assert isinstance(getattr(fw, attr), cls)
    for task in (fw.psns, fw.alignment, fw.output, fw.host):
        assert task.core is fw.core
    for task in (fw.psns, fw.alignment, fw.output):
        assert task.clock is fw.clock and task.status is fw.status
    assert fw.filter is fw.core.filter and fw.filter.host is fw.core


def test_the_check_sees_a_breach(tmp_path: Path) -> None:
    """The AST checks are not vacuous: a class reading a foreign ``self`` attribute and a read of
    ``self.clock._t_last_us`` are both found."""
    src = ("class T:\n    def __init__(self):\n        self.a = 1\n"
           "    def f(self):\n        return self.a + self.b + self.clock._t_last_us\n")
    node = ast.parse(src).body[0]
    assert isinstance(node, ast.ClassDef)
    own = _owned(node)
    assert "a" in own and "b" not in own and "f" in own
    hits = [e for e in ast.walk(node) if isinstance(e, ast.Attribute) and e.attr.startswith("_")
            and isinstance(e.value, ast.Attribute) and e.value.attr == "clock"]
    assert len(hits) == 1
