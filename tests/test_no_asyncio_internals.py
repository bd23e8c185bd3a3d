"""No module reads, writes or overrides a private field or method of asyncio (issue 43 item 2, D-10.E22).

The names are asyncio's own, taken from this interpreter: the private attributes of a fresh
``asyncio.SelectorEventLoop``, the private methods of its classes and of ``asyncio.Handle`` / ``asyncio.TimerHandle``
(their ``__slots__`` included), and the private names of asyncio's modules. Every Python file of the repository is
parsed; flagged are an import of a private name from asyncio, an attribute chain through asyncio's modules to a
private name (``asyncio.TimerHandle._run``), and an access to one of asyncio's private names on an event loop (an
expression that names a loop, or ``self`` in a class derived from an event loop or a handle), or anywhere for the
names only asyncio uses.
"""

from __future__ import annotations

import ast
import asyncio
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("emulator", "firmware_model", "protocols", "benchmarks", "tools", "examples", "studies", "tests")
#: asyncio's private names that are also ordinary names of the project's own objects (a link's ``_loop``, a
#: decoder's ``_closed``): flagged only on an event loop or a handle, not anywhere
COMMON = frozenset({"_loop", "_callback", "_args", "_context", "_closed", "_debug", "_selector", "_cancelled", "_repr",
                    "_transports", "_exception_handler", "_task_factory", "_signal_handlers", "_write_to_self",
                    "_make_self_pipe", "_process_events", "_stop", "_start", "_run", "_check_closed", "_thread_id",
                    "_add_reader", "_remove_reader", "_add_writer", "_remove_writer", "_ready", "_source_traceback",
                    "_internal_fds", "_default_executor", "_asyncgens", "_csock", "_ssock"})
LOOP_BASES = ("EventLoop", "EmulatorLoop", "Handle", "asyncio.")


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def asyncio_private_names() -> frozenset[str]:
    """asyncio's private attribute and method names on this interpreter."""
    names: set[str] = set()
    loop = asyncio.SelectorEventLoop()
    try:
        names.update(n for n in vars(loop) if _private(n))
    finally:
        loop.close()
    for cls in (asyncio.SelectorEventLoop, asyncio.Handle, asyncio.TimerHandle):
        for c in cls.__mro__:
            if c is object:
                continue
            names.update(n for n in vars(c) if _private(n))
            slots = c.__dict__.get("__slots__", ())
            names.update(n for n in ((slots,) if isinstance(slots, str) else slots) if _private(n))
    return frozenset(names)


def _text(node: ast.AST) -> str:
    return ast.unparse(node)


def _findings(path: Path, names: frozenset[str]) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: list[str] = []
    loop_classes: list[tuple[int, int]] = []  # line spans of classes derived from an event loop or a handle
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and any(b in _text(base) for base in node.bases for b in LOOP_BASES):
            loop_classes.append((node.lineno, node.end_lineno or node.lineno))
    for node in ast.walk(tree):
        where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "asyncio":
            out += [f"{where}: imports {a.name} from {node.module}" for a in node.names if _private(a.name)]
            if any(_private(part) for part in (node.module or "").split(".")):
                out.append(f"{where}: imports from {node.module}")
        elif isinstance(node, ast.Import):
            out += [f"{where}: imports {a.name}" for a in node.names
                    if a.name.split(".")[0] == "asyncio" and any(_private(p) for p in a.name.split("."))]
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            value = _text(node.value)
            if value == "asyncio" or value.startswith("asyncio."):
                out.append(f"{where}: {value}.{node.attr}")
            elif node.attr in names:
                on_loop = "loop" in value.lower() or (
                    value == "self" and any(a <= node.lineno <= b for a, b in loop_classes))
                if on_loop or node.attr not in COMMON:
                    out.append(f"{where}: {value}.{node.attr}")
        elif (isinstance(node, ast.FunctionDef) and node.name in names and _private(node.name)
              and any(a <= node.lineno <= b for a, b in loop_classes)):
            out.append(f"{where}: overrides {node.name}")
    return out


def test_the_names_are_asyncios() -> None:
    """The list is really asyncio's (else the test below checks nothing)."""
    names = asyncio_private_names()
    assert {"_scheduled", "_ready", "_run_once", "_when", "_timer_cancelled_count", "_clock_resolution",
            "_stopping", "_call_soon", "_callback", "_context"} <= names


def test_no_module_touches_asyncios_private_fields() -> None:
    names = asyncio_private_names()
    files = [p for folder in FOLDERS for p in sorted((ROOT / folder).rglob("*.py")) if ".venv" not in p.parts]
    assert len(files) > 300
    found = [f for p in files for f in _findings(p, names)]
    assert found == [], "\n".join(found)


def test_the_check_finds_what_the_old_fast_path_did(tmp_path: Path) -> None:
    """The check flags the uses the loop had before D-10.E22 (it is not blind to them)."""
    src = tmp_path / "old.py"
    src.write_text(
        "import asyncio\nfrom asyncio import events as _events\n"
        "from asyncio.format_helpers import _format_callback_source\n"
        "class L(asyncio.SelectorEventLoop):\n"
        "    def _run_once(self):\n        sched = self._scheduled\n        self._ready.append(sched[0])\n"
        "def f(loop, h):\n    return loop._timer_cancelled_count, h._when, asyncio.TimerHandle._run\n",
        encoding="utf-8")
    found = _findings(src, asyncio_private_names())
    for needle in ("_format_callback_source", "overrides _run_once", "self._scheduled", "self._ready",
                   "loop._timer_cancelled_count", "h._when", "asyncio.TimerHandle._run"):
        assert any(needle in f for f in found), (needle, found)
