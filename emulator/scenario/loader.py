"""Load a scenario YAML file, keeping the line and column of every key, and validate it.

Every problem is reported at once, each with ``file:line:column``, the field path and a
message; unknown keys are errors with a "did you mean" hint. Nothing runs from a scenario
that did not validate.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from ..errors import ScenarioError, ScenarioIssue
from .cross_checks import cross_check
from .schema import Scenario

__all__ = ["MAX_SCENARIO_BYTES", "MAX_YAML_DEPTH", "apply_overrides", "load_scenario", "load_yaml_file",
           "load_yaml_with_marks", "read_scenario_text", "scenario_from_text", "validate_scenario_data"]

Loc = tuple[Any, ...]

#: Largest scenario file read (bytes): the library's largest is 4 KB; checked before the YAML parser sees a byte.
MAX_SCENARIO_BYTES = 1 << 20
#: Deepest nesting of YAML collections accepted (the schema's deepest path is about 8); checked on the event stream
#: before anything is composed (PyYAML composes recursively: 100 KB of ``[`` took 294 s, then a RecursionError).
MAX_YAML_DEPTH = 64
_MERGE_TAG = "tag:yaml.org,2002:merge"


def _construct(node: yaml.Node, path: Loc, marks: dict[Loc, tuple[int, int]], file: str) -> Any:
    """Build Python data from a composed YAML node, recording where each path is."""
    if isinstance(node, yaml.MappingNode):
        out: dict[Any, Any] = {}
        for knode, vnode in node.value:
            if knode.tag == _MERGE_TAG:
                raise ScenarioError(ScenarioIssue(file, knode.start_mark.line + 1, knode.start_mark.column + 1,
                                                  _fmt_path(path), "YAML merge keys (<<) are not allowed: write the "
                                                  "keys out (decision D-8.9)"))
            key = _scalar(knode, file)
            if isinstance(key, (dict, list)):
                raise ScenarioError(ScenarioIssue(file, knode.start_mark.line + 1, knode.start_mark.column + 1,
                                                  _fmt_path(path), "mapping keys must be plain scalars"))
            if key in out:
                raise ScenarioError(ScenarioIssue(file, knode.start_mark.line + 1, knode.start_mark.column + 1,
                                                  _fmt_path((*path, key)), f"duplicate key {key!r}"))
            marks[(*path, key)] = (knode.start_mark.line + 1, knode.start_mark.column + 1)
            out[key] = _construct(vnode, (*path, key), marks, file)
        return out
    if isinstance(node, yaml.SequenceNode):
        items = []
        for i, item in enumerate(node.value):
            marks[(*path, i)] = (item.start_mark.line + 1, item.start_mark.column + 1)
            items.append(_construct(item, (*path, i), marks, file))
        return items
    return _scalar(node, file)


def _scalar(node: yaml.Node, file: str = "<scenario>") -> Any:
    loader = yaml.SafeLoader("")
    try:
        return loader.construct_object(node, deep=True)
    except yaml.YAMLError as exc:  # an unknown tag (!!python/...), a bad !!binary...: the node's place, one line
        m = node.start_mark
        problem = getattr(exc, "problem", None) or type(exc).__name__
        raise ScenarioError(ScenarioIssue(file, m.line + 1, m.column + 1, "", f"invalid YAML value: {problem}")) \
            from None
    finally:
        loader.dispose()


def _screen_events(text: str, file: str, stats: dict[str, int] | None = None) -> None:
    """Scan the event stream before anything is composed (nothing is expanded or built): refuse the first alias and
    the first collection nested deeper than :data:`MAX_YAML_DEPTH`. The scan stops there, so its cost is bounded by
    the text read up to that point (PyYAML's scanner reads at most 1024 characters ahead for a simple key).
    ``stats`` (tests of the bound) receives ``events`` read and ``chars`` of text consumed so far."""
    loader = yaml.SafeLoader(text)
    depth = 0
    st = stats if stats is not None else {}
    st["events"] = 0
    try:
        while loader.check_event():
            ev = loader.get_event()
            st["events"] += 1
            st["chars"] = loader.index  # characters the reader has consumed (the scanner's lookahead included)
            m = ev.start_mark
            line, col = (m.line + 1, m.column + 1) if m else (None, None)
            if isinstance(ev, yaml.AliasEvent):
                raise ScenarioError(ScenarioIssue(file, line, col, "", f"YAML aliases are not allowed "
                                                  f"(*{ev.anchor}): write the value out"))
            if isinstance(ev, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    raise ScenarioError(ScenarioIssue(file, line, col, "", f"YAML nested deeper than "
                                                      f"{MAX_YAML_DEPTH} levels (a scenario needs about 8)"))
            elif isinstance(ev, yaml.CollectionEndEvent):
                depth -= 1
    finally:
        loader.dispose()


def load_yaml_with_marks(text: str, file: str = "<scenario>") -> tuple[Any, dict[Loc, tuple[int, int]]]:
    """Parse YAML text; return the data and a map from field path to (line, column), 1-based.

    Aliases (``*name``, also in ``<<: *name``) are refused: a scenario may come from anyone, and aliases expand to
    exponential size (billion laughs) or refer to themselves (docs/hostile-input.md). So are texts longer than
    :data:`MAX_SCENARIO_BYTES` (before parsing), collections nested deeper than :data:`MAX_YAML_DEPTH` (before
    composing) and merge keys ``<<`` (decision D-8.9)."""
    if len(text) > MAX_SCENARIO_BYTES:
        raise ScenarioError(ScenarioIssue(file, None, None, "", f"larger than {MAX_SCENARIO_BYTES >> 20} MiB "
                                          "(a scenario is a few KB)"))
    try:
        _screen_events(text, file)
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else None
        col = mark.column + 1 if mark else None
        problem = exc.problem or str(exc)
        raise ScenarioError(ScenarioIssue(file, line, col, "", f"invalid YAML: {problem}")) from exc
    except yaml.YAMLError as exc:
        raise ScenarioError(ScenarioIssue(file, None, None, "", f"invalid YAML: {exc}")) from exc
    if root is None:
        raise ScenarioError(ScenarioIssue(file, 1, 1, "", "the file is empty"))
    marks: dict[Loc, tuple[int, int]] = {(): (root.start_mark.line + 1, root.start_mark.column + 1)}
    data = _construct(root, (), marks, file)
    return data, marks


def _fmt_path(loc: Loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _model_at(loc: Loc) -> type[BaseModel] | None:
    """The pydantic model class that owns the field at ``loc`` (best effort, for hints)."""
    model: Any = Scenario
    for part in loc:
        if isinstance(part, int):
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return None
        field = model.model_fields.get(str(part))
        if field is None:
            return None
        ann = field.annotation
        model = _unwrap(ann)
    return model if isinstance(model, type) and issubclass(model, BaseModel) else None


def _unwrap(ann: Any) -> Any:
    args = getattr(ann, "__args__", None)
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    if args:
        for a in args:
            u = _unwrap(a)
            if isinstance(u, type) and issubclass(u, BaseModel):
                return u
    return ann


def _issue_from_error(err: ErrorDetails, marks: dict[Loc, tuple[int, int]], file: str) -> ScenarioIssue:
    loc: Loc = tuple(p for p in err.get("loc", ()) if not (isinstance(p, str) and p.startswith("function-")))
    # drop pydantic's union-member tags ("static", "Static[...]") that are not data keys
    probe = loc
    while probe and probe not in marks:
        probe = probe[:-1]
    line, col = marks.get(probe, (None, None))
    msg = err.get("msg", "invalid value")
    if err.get("type") == "extra_forbidden" and loc:
        key = str(loc[-1])
        owner = _model_at(loc[:-1])
        hint = ""
        if owner is not None:
            close = difflib.get_close_matches(key, list(owner.model_fields), n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else f"; allowed keys: {', '.join(owner.model_fields)}"
        msg = f"unknown key {key!r}{hint}"
    elif "input" in err and err.get("type") not in ("missing",):
        inp = err["input"]
        if not isinstance(inp, (dict, list)):
            msg = f"{msg} (got {inp!r})"
    return ScenarioIssue(file, line, col, _fmt_path(loc), msg)


def validate_scenario_data(data: Any, marks: dict[Loc, tuple[int, int]], file: str = "<scenario>",
                           base_dir: Path | None = None, check_environment: bool = True) -> Scenario:
    """Validate parsed YAML against the schema; raise :class:`ScenarioError` with every issue.

    ``check_environment``: also check what the run needs from this machine (referenced files, serial
    devices); a replay, which uses neither, turns it off."""
    if not isinstance(data, dict):
        raise ScenarioError(ScenarioIssue(file, 1, 1, "", "a scenario must be a mapping of keys to values"))
    try:
        scn = Scenario.model_validate(data, context={"base_dir": base_dir})
    except ValidationError as exc:
        issues = [_issue_from_error(e, marks, file) for e in exc.errors(include_url=False)]
        issues.sort(key=lambda i: (i.line or 0, i.column or 0))
        raise ScenarioError(issues) from None
    scn._source_file = file
    scn._base_dir = str(base_dir) if base_dir is not None else None
    scn._marks = marks
    problems = cross_check(scn, environment=check_environment)
    if problems:
        issues = []
        for loc, msg in problems:
            probe = loc
            while probe and probe not in marks:
                probe = probe[:-1]
            line, col = marks.get(probe, (None, None))
            issues.append(ScenarioIssue(file, line, col, _fmt_path(loc), msg))
        issues.sort(key=lambda i: (i.line or 0, i.column or 0))
        raise ScenarioError(issues)
    return scn


def apply_overrides(data: Any, overrides: list[str] | tuple[str, ...], marks: dict[Loc, tuple[int, int]]
                    ) -> dict[Loc, str]:
    """Apply ``--set dotted.key=value`` overrides to parsed scenario data, in place.

    The value is read as YAML (``5``, ``true``, ``pty://uart0``, ``{a: 1}``); a number in the path indexes a list
    (``faults.0.start_s``). The overridden keys lose their file position (``marks``). Returns each override's
    location -> its text, so that validation problems there name the override rather than the file.
    """
    where: dict[Loc, str] = {}
    for raw in overrides:
        key, eq, text = raw.partition("=")
        key = key.strip()
        if not eq or not key or any(not k for k in key.split(".")):
            raise ScenarioError(ScenarioIssue(f"--set {raw}", None, None, "", "expected --set dotted.key=value "
                                              "(for example --set duration_s=30 or --set links.host.url=pty://uart0)"))
        try:
            value = yaml.safe_load(text) if text.strip() else ""
        except yaml.YAMLError as exc:
            raise ScenarioError(ScenarioIssue(f"--set {raw}", None, None, key, f"the value is not YAML: {exc}")) \
                from None
        loc: Loc = tuple(int(k) if k.isdigit() else k for k in key.split("."))
        node = data
        for i, k in enumerate(loc[:-1]):
            nxt = loc[i + 1]
            if isinstance(node, list) and isinstance(k, int):
                if k >= len(node):
                    raise ScenarioError(ScenarioIssue(f"--set {raw}", None, None, _fmt_path(loc[: i + 1]),
                                                      f"index {k} is past the end (the list has {len(node)} items)"))
            elif isinstance(node, dict):
                if not isinstance(node.get(k), (dict, list)):
                    node[k] = [] if isinstance(nxt, int) else {}
            else:
                raise ScenarioError(ScenarioIssue(f"--set {raw}", None, None, _fmt_path(loc[:i]),
                                                  "is not a mapping or a list"))
            node = node[k]
        last = loc[-1]
        if isinstance(node, dict) or (isinstance(node, list) and isinstance(last, int) and last < len(node)):
            node[last] = value
        else:
            raise ScenarioError(ScenarioIssue(f"--set {raw}", None, None, _fmt_path(loc), "cannot be set here"))
        for m in [m for m in marks if m[: len(loc)] == loc]:
            del marks[m]
        where[loc] = raw
    return where


def read_scenario_text(p: Path, file: str) -> str:
    """The text of a scenario file, read in one bounded piece: at most :data:`MAX_SCENARIO_BYTES` + 1 bytes are
    read (a larger file, or an endless one such as ``/dev/zero``, is refused before any parsing)."""
    try:
        if p.is_dir():
            raise ScenarioError(ScenarioIssue(file, None, None, "", "is a directory, not a scenario file"))
        with open(p, "rb") as f:
            raw = f.read(MAX_SCENARIO_BYTES + 1)
    except FileNotFoundError:
        raise ScenarioError(ScenarioIssue(file, None, None, "", "no such file")) from None
    except IsADirectoryError:
        raise ScenarioError(ScenarioIssue(file, None, None, "", "is a directory, not a scenario file")) from None
    except OSError as exc:
        raise ScenarioError(ScenarioIssue(file, None, None, "", f"cannot read: {exc.strerror}")) from None
    if len(raw) > MAX_SCENARIO_BYTES:
        raise ScenarioError(ScenarioIssue(file, None, None, "", f"larger than {MAX_SCENARIO_BYTES >> 20} MiB "
                                          "(a scenario is a few KB)"))
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(ScenarioIssue(file, None, None, "", f"not UTF-8 text ({exc.reason})")) from None


def load_yaml_file(path: str | Path, file: str | None = None) -> Any:
    """Plain data of a YAML file a scenario names (a spec sheet...), bounded as a scenario is: one read of at most
    :data:`MAX_SCENARIO_BYTES`, nesting and aliases screened before anything is built, merge keys and unknown tags
    refused; a :class:`~emulator.errors.ScenarioError` with file and line otherwise."""
    file = file or str(path)
    data, _marks = load_yaml_with_marks(read_scenario_text(Path(path), file), file)
    return data


def load_scenario(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scenario:
    """Read, parse and validate a scenario file; ``overrides``: ``dotted.key=value`` (:func:`apply_overrides`)."""
    p = Path(path)
    return scenario_from_text(read_scenario_text(p, str(path)), str(path), p.resolve().parent, overrides)


def scenario_from_text(text: str, file: str, base_dir: Path, overrides: list[str] | tuple[str, ...] = ()) -> Scenario:
    """Parse and validate the ``text`` of scenario ``file`` (read by :func:`read_scenario_text`; ``base_dir`` its
    directory), as :func:`load_scenario` does: for a caller that needs the text itself too (a campaign), so the
    file is read once, bounded."""
    data, marks = load_yaml_with_marks(text, file)
    if not overrides:
        return validate_scenario_data(data, marks, file, base_dir=base_dir)
    if not isinstance(data, dict):
        raise ScenarioError(ScenarioIssue(file, 1, 1, "", "a scenario must be a mapping of keys to values"))
    where = apply_overrides(data, overrides, marks)
    try:
        return validate_scenario_data(data, marks, file, base_dir=base_dir)
    except ScenarioError as exc:
        by_path = {_fmt_path(loc): raw for loc, raw in where.items()}
        for issue in exc.issues:
            for path_text, raw in by_path.items():
                if issue.path == path_text or issue.path.startswith((path_text + ".", path_text + "[")):
                    issue.file, issue.line, issue.column = f"{file} (--set {raw})", None, None
        raise
