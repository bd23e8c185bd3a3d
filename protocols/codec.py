"""Fast ``struct`` codecs derived from the declarative ``construct`` specs: one declaration per message.

Every wire message is declared once, as a ``construct`` ``Struct`` whose fields carry their ICD docs. A
:class:`StructCodec` walks that ``Struct``'s subcons at import time and derives a ``struct.Struct`` that
reads or writes the whole layout in one C call, and the field names that give each unpacked item its
meaning. The hot paths decode and encode by field *name*: :meth:`StructCodec.decoder` generates, from the
names, a function that builds a frame dataclass from the unpacked items (each dataclass field is matched to
the spec field of the same name, or of the name given in ``rename``), and :meth:`StructCodec.encoder` /
:meth:`StructCodec.packer` generate the inverse. Nothing is declared by position anywhere else, so a field
added to a spec either reaches its dataclass or stops the import.

Derivation rules (subcon -> ``struct`` items):

============================================  ==================================================================
subcon                                        ``struct`` items, value
============================================  ==================================================================
``Int8ub`` .. ``Int64sl``, ``Float32l`` ..    its own format character; value as ``construct`` gives it
``Int24ul/sl/ub/sb`` (``BytesInteger(3)``)    two items, the low 16 bits (``H``) and the high byte (``b``
                                              signed / ``B`` unsigned) in wire order; value ``lo | hi << 16``
                                              (the high byte's sign extends the word); encoding splits the value
                                              the same way, so a value outside 24 bits raises ``ValueError``
``Array(n, element)``, ``n`` an int           ``n`` times the element's items; value a tuple
``Bytes(n)``, ``n`` an int                    ``{n}s``; value ``bytes``
``Const(value, subcon)``                      the subcon's items; decoding checks the value (``ValueError``
                                              otherwise) and encoding writes it; not a value field
``Padding(n)``                                ``{n}x``; not a value field
============================================  ==================================================================

A spec holding anything else (a length read from another field, a nested ``Struct``, a ``BitStruct``)
raises ``TypeError``: such a message stays on the ``construct`` path, or its fixed parts get their own
codecs (:func:`subspec`). Multi-byte fields must share one byte order.

Every codec keeps its reference beside the fast path (:meth:`StructCodec.decode` / :meth:`StructCodec.encode`
run ``construct``; :meth:`StructCodec.decode_fast` / :meth:`StructCodec.encode_fast` the derived ``struct``),
and :data:`CODECS` lists every codec and every generated dataclass binding, so
``tests/protocols/test_derived_codecs.py`` compares them field by field on the golden vectors and on random
values.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import MISSING, dataclass, field, fields
from itertools import starmap
from typing import Any

from construct import Array, Bytes, BytesInteger, Const, Construct, FormatField, Padded, Pass, Renamed, Struct

from ._fastinit import fast_new

__all__ = ["CODECS", "Binding", "StructCodec", "subspec"]

#: Every derived codec, in import order (the equivalence test walks it).
CODECS: list[StructCodec] = []


@dataclass(frozen=True)
class _Item:
    """One value field of the spec: its name, kind and place in the unpacked tuple."""

    name: str
    kind: str  #: "scalar", "int24", "array", "array24", "bytes"
    first: int  #: index of its first item in the unpacked tuple
    count: int  #: elements (1 for a scalar, the length for bytes)


@dataclass(frozen=True)
class Binding:
    """A generated dataclass decoder or encoder (:attr:`call_fast`) beside its ``construct`` reference
    (:meth:`call`), and how it maps the spec's fields to the dataclass's.

    ``fields`` maps each dataclass field taken from the spec to ``(spec field, conversion or None)``; the
    conversion turns the wire value into the dataclass value (decoder) or back (encoder). ``params`` are the
    further parameters of a decoder (dataclass fields the spec does not carry) or the parameters of an
    ``encode_args`` encoder.
    """

    codec: StructCodec
    cls: type
    #: "decode", "decode_all" (back-to-back records), "encode" (from an object), "encode_all" (objects, back to
    #: back) or "encode_args" (from the fields as arguments)
    direction: str
    fields: Mapping[str, tuple[str, Callable[[Any], Any] | None]]
    call_fast: Callable[..., Any]
    params: tuple[str, ...] = ()
    fixed: Mapping[str, Any] = field(default_factory=dict)  #: spec fields an encoder writes as constants

    def _from_wire(self, v: Mapping[str, Any], others: Sequence[Any]) -> Any:
        kw = {c: (v[s] if conv is None else conv(v[s])) for c, (s, conv) in self.fields.items()}
        kw.update(zip(self.params, others))
        return self.cls(**kw)

    def _to_wire(self, get: Callable[[str], Any]) -> bytes:
        v = {s: (get(c) if conv is None else conv(get(c))) for c, (s, conv) in self.fields.items()}
        return self.codec.encode({**v, **self.fixed})

    def call(self, *args: Any) -> Any:
        """The reference: what :attr:`call_fast` returns, computed through ``construct`` by field name."""
        if self.direction == "decode":
            buf, off, *others = (*args, 0) if len(args) == 1 else args
            return self._from_wire(self.codec.decode(buf, off), others)
        if self.direction == "decode_all":
            buf, *others = args
            size = self.codec.size
            if len(buf) % size:
                raise ValueError(f"{self.codec.name}: {len(buf)} bytes are not whole records of {size}")
            return tuple(self._from_wire(self.codec.decode(buf, off), others) for off in range(0, len(buf), size))
        if self.direction == "encode":
            return self._to_wire(lambda c: getattr(args[0], c))
        if self.direction == "encode_all":
            return b"".join([self._to_wire(functools.partial(getattr, o)) for o in args[0]])
        named = dict(zip(self.params, args))
        return self._to_wire(named.__getitem__)


def _unwrap(sc: Construct) -> tuple[str | None, Construct]:
    name = None
    while isinstance(sc, Renamed):
        name = name or sc.name
        sc = sc.subcon
    return name, sc


def subspec(spec: Struct, first: str, last: str) -> Struct:
    """The ``Struct`` of the contiguous fields ``first`` .. ``last`` of ``spec`` (the same subcon objects).

    For codecs of the fixed parts of a message whose whole layout is variable (a header before a payload
    of declared length).
    """
    names = [_unwrap(sc)[0] for sc in spec.subcons]
    i, j = names.index(first), names.index(last)
    return Struct(*spec.subcons[i : j + 1])


def _order(sc: Construct) -> str:
    """"<", ">" or "" (single byte / no order) of a leaf subcon."""
    if isinstance(sc, FormatField):
        return "" if struct.calcsize(sc.fmtstr) == 1 else sc.fmtstr[0]
    if isinstance(sc, BytesInteger):
        return "<" if sc.swapped else ">"
    return ""


def _leaf(sc: Construct, where: str) -> tuple[str, str]:
    """``(struct chars, kind)`` of a leaf subcon: kind "scalar", "int24" or "bytes"."""
    if isinstance(sc, FormatField):
        return sc.fmtstr[1:], "scalar"
    if isinstance(sc, BytesInteger) and sc.length == 3:
        hi = "b" if sc.signed else "B"
        return ("H" + hi if sc.swapped else hi + "H"), "int24"
    if isinstance(sc, Bytes) and isinstance(sc.length, int):
        return f"{sc.length}s", "bytes"
    raise TypeError(f"{where}: {sc!r} has no struct equivalent (see protocols.codec)")


class StructCodec:
    """The ``struct`` codec of one fixed-size ``construct`` ``Struct`` (see the module docstring).

    Attributes
    ----------
    spec:
        The declaration.
    struct:
        The derived ``struct.Struct`` (one item per scalar, two per 24-bit word, consts and padding included).
    size:
        Bytes of the layout.
    names:
        The value fields (not consts, not padding), in wire order.
    """

    def __init__(self, spec: Struct, name: str) -> None:
        self.spec = spec
        self.name = name
        self.bindings: list[Binding] = []
        fmt: list[str] = []
        orders: set[str] = set()
        items: list[_Item] = []
        consts: list[tuple[int, Any, str, int]] = []  # (index of its item, value, struct chars, byte offset)
        n = 0  # items so far
        for sc in spec.subcons:
            fname, inner = _unwrap(sc)
            where = f"{name}.{fname}"
            if isinstance(inner, Padded) and isinstance(inner.subcon, Pass) and isinstance(inner.length, int):
                fmt.append(f"{inner.length}x")
                continue
            if fname is None:
                raise TypeError(f"{name}: unnamed field {inner!r}")
            if isinstance(inner, Const):
                _, leaf = _unwrap(inner.subcon)
                chars, kind = _leaf(leaf, where)
                if kind == "int24":
                    raise TypeError(f"{where}: a 24-bit Const is not supported")
                orders.add(_order(leaf))
                consts.append((n, inner.value, chars, struct.calcsize("<" + "".join(fmt))))
                fmt.append(chars)
                n += 1
                continue
            if isinstance(inner, Array):
                if not isinstance(inner.count, int):
                    raise TypeError(f"{where}: Array of variable count has no struct equivalent")
                _, el = _unwrap(inner.subcon)
                chars, kind = _leaf(el, where)
                if kind == "bytes":
                    raise TypeError(f"{where}: Array of Bytes is not supported")
                orders.add(_order(el))
                per = 2 if kind == "int24" else 1
                items.append(_Item(fname, "array24" if kind == "int24" else "array", n, inner.count))
                fmt.append(chars * inner.count)
                n += per * inner.count
                continue
            chars, kind = _leaf(inner, where)
            orders.add(_order(inner))
            items.append(_Item(fname, kind, n, inner.length if kind == "bytes" else 1))
            fmt.append(chars)
            n += 2 if kind == "int24" else 1
        orders.discard("")
        if len(orders) > 1:
            raise TypeError(f"{name}: fields of both byte orders")
        self.order = orders.pop() if orders else "<"
        self.struct = struct.Struct(self.order + "".join(fmt))
        self.size = self.struct.size
        if spec.sizeof() != self.size:  # pragma: no cover - a rule above is wrong
            raise AssertionError(f"{name}: derived {self.size} bytes, construct says {spec.sizeof()}")
        self._items = tuple(items)
        self._consts = tuple(consts)
        #: ``(byte offset, bytes)`` of every constant of the layout
        self.constants = tuple((off, struct.pack(self.order + chars, v) if not isinstance(v, bytes) else v)
                               for _, v, chars, off in consts)
        self._nitems = n
        self.names = tuple(it.name for it in items)
        self.decode_fast: Callable[[bytes | bytearray | memoryview, int], dict[str, Any]] = self._gen_decode_dict()
        self.encode_fast: Callable[[Mapping[str, Any]], bytes] = self._gen_encode_dict()
        self.packer: Callable[..., bytes] = self._gen_packer()
        CODECS.append(self)

    def __repr__(self) -> str:
        return f"StructCodec({self.name}, {self.struct.format!r})"

    # -- references: construct -------------------------------------------------------------------
    def decode(self, buf: bytes | bytearray | memoryview, offset: int = 0) -> dict[str, Any]:
        """Reference decode through ``construct``: the value fields by name (arrays as tuples)."""
        c = self.spec.parse(bytes(buf[offset : offset + self.size]))
        return {k: (tuple(c[k]) if isinstance(c[k], list) else c[k]) for k in self.names}

    def encode(self, values: Mapping[str, Any]) -> bytes:
        """Reference encode through ``construct``."""
        return bytes(self.spec.build(dict(values)))

    # -- code generation -------------------------------------------------------------------------
    def _unpack_targets(self) -> tuple[list[str], dict[str, str]]:
        """Local names for every unpacked item, and the expression of each value field."""
        targets = [f"_c{i}" for i in range(self._nitems)]
        for i, *_ in self._consts:
            targets[i] = f"_k{i}"
        expr: dict[str, str] = {}
        for it in self._items:
            if it.kind in ("scalar", "bytes"):
                targets[it.first] = f"f_{it.name}"
                expr[it.name] = f"f_{it.name}"
            elif it.kind == "array":
                names = [f"f_{it.name}_{k}" for k in range(it.count)]
                targets[it.first : it.first + it.count] = names
                expr[it.name] = "(" + ", ".join(names) + ",)"
            else:  # int24 or array24: (lo, hi) pairs
                words = []
                for k in range(it.count):
                    lo, hi = f"f_{it.name}_{k}_lo", f"f_{it.name}_{k}_hi"
                    i = it.first + 2 * k
                    targets[i : i + 2] = [lo, hi] if self.order == "<" else [hi, lo]
                    words.append(f"({lo} | {hi} << 16)")
                expr[it.name] = words[0] if it.kind == "int24" else "(" + ", ".join(words) + ",)"
        return targets, expr

    def _const_checks(self) -> list[str]:
        return [f"    if _k{i} != _K{i}:\n        raise ValueError(f'{self.name}: {{_k{i}!r}} where the constant "
                f"{{_K{i}!r}} belongs')\n" for i, *_ in self._consts]

    def _namespace(self) -> dict[str, Any]:
        ns: dict[str, Any] = {"_unpack_from": self.struct.unpack_from, "_iter_unpack": self.struct.iter_unpack,
                              "_pack": self.struct.pack, "_StructError": struct.error}
        for i, v, *_ in self._consts:
            ns[f"_K{i}"] = v
        return ns

    def _compile(self, src: str, ns: dict[str, Any], fn: str) -> Callable[..., Any]:
        exec(compile(src, f"<codec {self.name}>", "exec"), ns)
        f: Callable[..., Any] = ns[fn]
        f.__qualname__ = f"{self.name}.{fn}"
        return f

    def _unpack_stmt(self, targets: list[str], source: str) -> str:
        lhs = ", ".join(targets) + ("," if len(targets) == 1 else "")
        return (f"    try:\n        {lhs} = {source}\n    except _StructError as exc:\n"
                f"        raise ValueError(f'{self.name}: {{exc}}') from exc\n")

    def _gen_decode_dict(self) -> Callable[[bytes | bytearray | memoryview, int], dict[str, Any]]:
        targets, expr = self._unpack_targets()
        body = self._unpack_stmt(targets, "_unpack_from(_buf, _off)") + "".join(self._const_checks())
        body += "    return {" + ", ".join(f"{n!r}: {expr[n]}" for n in self.names) + "}\n"
        return self._compile(f"def decode_fast(_buf, _off=0):\n{body}", self._namespace(), "decode_fast")

    def _pack_args(self, value: Callable[[str], str]) -> tuple[str, str]:
        """Statements to run first and the argument list of ``_pack``, ``value(field)`` being each value field's
        expression. Arrays are taken apart by an unpacking assignment (which refuses a wrong element count, as
        ``construct`` does); 24-bit words are then split into their two items."""
        pre: list[str] = []
        args = [""] * self._nitems
        for i, *_ in self._consts:
            args[i] = f"_K{i}"
        for it in self._items:
            v = value(it.name)
            if it.kind == "scalar":
                args[it.first] = v
            elif it.kind == "bytes":  # struct would pad or cut a wrong length silently; construct refuses it
                b = f"_b_{it.name}"
                pre.append(f"        {b} = {v}\n        if len({b}) != {it.count}:\n"
                           f"            raise ValueError('{self.name}.{it.name} needs {it.count} bytes')\n")
                args[it.first] = b
            elif it.kind == "array":
                # one unpacking assignment: refuses a wrong element count, cheaper than indexing v repeatedly
                elems = [f"_e_{it.name}_{k}" for k in range(it.count)]
                pre.append(f"        {', '.join(elems)}{',' if it.count == 1 else ''} = {v}\n")
                args[it.first : it.first + it.count] = elems
            else:
                words = [f"_w_{it.name}_{k}" for k in range(it.count)]
                pre.append(f"        {', '.join(words)}{',' if it.count == 1 else ''} = {v}\n" if it.kind == "array24"
                           else f"        {words[0]} = {v}\n")
                for k, w in enumerate(words):
                    lo, hi = f"{w} & 0xFFFF", f"{w} >> 16"
                    args[it.first + 2 * k : it.first + 2 * k + 2] = [lo, hi] if self.order == "<" else [hi, lo]
        return "".join(pre), ", ".join(args)

    def _pack_stmt(self, pre_args: tuple[str, str]) -> str:
        pre, args = pre_args
        return (f"    try:\n{pre}        return _pack({args})\n"
                f"    except (_StructError, TypeError, OverflowError) as exc:\n"
                f"        raise ValueError(f'{self.name}: {{exc}}') from exc\n")

    def _gen_encode_dict(self) -> Callable[[Mapping[str, Any]], bytes]:
        src = "def encode_fast(_v):\n" + self._pack_stmt(self._pack_args(lambda n: f"_v[{n!r}]"))
        return self._compile(src, self._namespace(), "encode_fast")

    def _gen_packer(self) -> Callable[..., bytes]:
        # keyword-only parameters named as the spec's fields
        src = f"def pack(*, {', '.join(self.names)}):\n" if self.names else "def pack():\n"
        src += self._pack_stmt(self._pack_args(lambda n: n))
        return self._compile(src, self._namespace(), "pack")

    # -- dataclass bindings ----------------------------------------------------------------------
    def _map(self, cls: type, rename: Mapping[str, str], ignore: Sequence[str],
             convert: Mapping[str, Callable[[Any], Any]]) -> tuple[dict[str, str], list[Any]]:
        """Dataclass field -> spec field, checked both ways by name; and the dataclass fields in order."""
        unknown = (set(rename) | set(ignore) | set(convert)) - set(self.names)
        if unknown:
            raise TypeError(f"{self.name}: rename/ignore/convert name no field of the spec: {sorted(unknown)}")
        cls_fields = [f for f in fields(cls) if f.init]
        by_cls = {rename.get(n, n): n for n in self.names if n not in ignore}
        missing = set(by_cls) - {f.name for f in cls_fields}
        if missing:
            raise TypeError(f"{self.name}: spec fields {sorted(by_cls[m] for m in missing)} have no field in "
                            f"{cls.__name__} (rename or ignore them)")
        return by_cls, cls_fields

    def decoder(self, cls: type, *, rename: Mapping[str, str] | None = None, ignore: Sequence[str] = (),
                convert: Mapping[str, Callable[[Any], Any]] | None = None, many: bool = False) -> Callable[..., Any]:
        """Generate ``decode(buf, offset, *others) -> cls``, the dataclass built from the spec by field name.

        Every spec value field goes to the dataclass field of the same name (or ``rename[spec name]``), through
        ``convert[spec name]`` if given, unless it is in ``ignore`` (a CRC checked elsewhere). Dataclass fields
        that the spec does not provide become further parameters, in dataclass order, with the dataclass's
        defaults (``offset`` defaults to 0 unless one of them is required). ``many=True`` generates
        ``decode_all(buf, *others) -> tuple[cls, ...]`` over back-to-back
        records instead.
        """
        rename, convert = rename or {}, convert or {}
        by_cls, cls_fields = self._map(cls, rename, ignore, convert)
        targets, expr = self._unpack_targets()
        ns = self._namespace()
        ns["_cls"] = fast_new(cls)  # cls itself, or its faster equal (protocols._fastinit)
        params, args = [], []
        mapping: dict[str, tuple[str, Callable[[Any], Any] | None]] = {}
        for f in cls_fields:
            sname = by_cls.get(f.name)
            if sname is None:
                if f.default is not MISSING:
                    ns[f"_d_{f.name}"] = f.default
                    params.append(f"{f.name}=_d_{f.name}")
                else:
                    params.append(f.name)
                args.append(f.name)
                continue
            conv = convert.get(sname)
            mapping[f.name] = (sname, conv)
            if conv is None:
                args.append(expr[sname])
            else:
                ns[f"_cv_{sname}"] = conv
                args.append(f"_cv_{sname}({expr[sname]})")
        extra = "".join(", " + p for p in params)
        call = f"_cls({', '.join(args)})"
        # The unpacked items are exactly the dataclass's fields in order (scalars only, no conversion, nothing
        # else): hand the tuple over whole, which CPython does faster than through named locals.
        direct = (not params and not self._consts and len(targets) == len(cls_fields)
                  and all(it.kind in ("scalar", "bytes") for it in self._items)
                  and [f.name for f in cls_fields] == [rename.get(n, n) for n in self.names]
                  and not convert and not ignore)
        ns["_starmap"] = starmap
        if many and direct:
            src = (f"def decode_all(_buf):\n    try:\n        return tuple(_starmap(_cls, _iter_unpack(_buf)))\n"
                   f"    except _StructError as exc:\n        raise ValueError(f'{self.name}: {{exc}}') from exc\n")
            fn = self._compile(src, ns, "decode_all")
        elif direct:
            src = (f"def decode(_buf, _off=0):\n    try:\n        return _cls(*_unpack_from(_buf, _off))\n"
                   f"    except _StructError as exc:\n        raise ValueError(f'{self.name}: {{exc}}') from exc\n")
            fn = self._compile(src, ns, "decode")
        elif many:
            if self._consts:
                raise TypeError(f"{self.name}: decode_all of records with constants is not supported")
            lhs = ", ".join(targets) + ("," if len(targets) == 1 else "")
            src = (f"def decode_all(_buf{extra}):\n    try:\n        return tuple([{call} for {lhs} in "
                   f"_iter_unpack(_buf)])\n    except _StructError as exc:\n"
                   f"        raise ValueError(f'{self.name}: {{exc}}') from exc\n")
            fn = self._compile(src, ns, "decode_all")
        else:
            off = "_off" if any("=" not in p for p in params) else "_off=0"  # a required field follows
            src = (f"def decode(_buf, {off}{extra}):\n" + self._unpack_stmt(targets, "_unpack_from(_buf, _off)")
                   + "".join(self._const_checks()) + f"    return {call}\n")
            fn = self._compile(src, ns, "decode")
        extra_names = tuple(p.split("=", 1)[0] for p in params)
        self.bindings.append(Binding(self, cls, "decode_all" if many else "decode", mapping, fn, extra_names))
        return fn

    def unpacker(self, cls: type) -> Callable[[bytes | bytearray | memoryview, int], tuple[Any, ...]]:
        """``struct.unpack_from`` of this codec, for ``cls(*unpack_from(buf, offset))`` on the hottest paths.

        Only for a dataclass whose fields *are* the spec's value fields, by name and in order, scalars only
        (refused with ``TypeError`` otherwise): then the unpacked tuple is the dataclass's argument list and
        the call saves the generated decoder's frame. The generated decoder is registered as well, so the
        equivalence test covers the dataclass.
        """
        self.decoder(cls)
        if any(it.kind not in ("scalar", "bytes") for it in self._items) or self._consts \
                or [f.name for f in fields(cls) if f.init] != list(self.names):
            raise TypeError(f"{self.name}: the fields of {cls.__name__} are not the spec's fields in order")
        unpack: Callable[[bytes | bytearray | memoryview, int], tuple[Any, ...]] = self.struct.unpack_from
        return unpack

    def columns_packer(self, cls: type) -> Callable[..., bytes]:
        """``encode_columns(*columns) -> bytes``: records packed back to back from one sequence per value field (in
        the spec's order: ``encode_columns(xs, ys, ...)``), the bytes of :meth:`encoder` ``(cls, many=True)`` on
        the objects ``cls(x, y, ...)`` without building them (a sender that holds its values as columns).

        Only for a dataclass whose fields *are* the spec's value fields, by name and in order, scalars only (as
        :meth:`unpacker`; ``TypeError`` otherwise); the objects' encoder is registered as well, so the equivalence
        test covers the dataclass. Columns of different lengths, and values the layout cannot hold, raise
        ``ValueError``.
        """
        self.encoder(cls, many=True)
        if any(it.kind != "scalar" for it in self._items) or self._consts \
                or [f.name for f in fields(cls) if f.init] != list(self.names):
            raise TypeError(f"{self.name}: the fields of {cls.__name__} are not the spec's fields in order")
        pack, name = self.struct.pack, self.name

        def encode_columns(*columns: Sequence[Any]) -> bytes:
            if len(columns) != len(self.names) or len({len(c) for c in columns}) > 1:
                raise ValueError(f"{name}: {len(self.names)} columns of one length expected")
            try:
                return b"".join(map(pack, *columns))
            except (struct.error, TypeError, OverflowError) as exc:
                raise ValueError(f"{name}: {exc}") from exc

        encode_columns.__qualname__ = f"{name}.encode_columns"
        return encode_columns

    def encoder(self, cls: type, *, rename: Mapping[str, str] | None = None,
                convert: Mapping[str, Callable[[Any], Any]] | None = None, fixed: Mapping[str, Any] | None = None,
                from_args: bool = False, many: bool = False) -> Callable[..., bytes]:
        """Generate ``encode(obj) -> bytes``: each spec field read from the attribute of the same name.

        ``rename`` and ``convert`` as in :meth:`decoder` (``convert`` here maps the attribute value to the wire
        value); ``fixed`` gives spec fields a constant value instead (a message id). With ``from_args=True`` the
        function takes the dataclass's fields that the spec carries as its parameters instead of one object,
        in the dataclass's order and under its names (``encode(seq, time_s, ...)``): for an output path that
        has the values but no object. ``many=True`` generates ``encode_all(objs) -> bytes`` instead, the records
        back to back (scalar fields only). Every other value field of the spec must come from the dataclass.
        """
        rename, convert, fixed = rename or {}, convert or {}, fixed or {}
        unknown = set(fixed) - set(self.names)
        if unknown:
            raise TypeError(f"{self.name}: fixed names no field of the spec: {sorted(unknown)}")
        by_cls, cls_fields = self._map(cls, rename, tuple(fixed), convert)
        ns = self._namespace()
        mapping: dict[str, tuple[str, Callable[[Any], Any] | None]] = {}
        for cname, sname in by_cls.items():
            mapping[cname] = (sname, convert.get(sname))
            if sname in convert:
                ns[f"_cv_{sname}"] = convert[sname]
        for sname, v in fixed.items():
            ns[f"_F_{sname}"] = v

        def value(sname: str) -> str:
            if sname in fixed:
                return f"_F_{sname}"
            attr = rename.get(sname, sname) if from_args else f"_o.{rename.get(sname, sname)}"
            return f"_cv_{sname}({attr})" if sname in convert else attr

        pre, args = self._pack_args(value)
        if many:
            if pre or from_args:
                raise TypeError(f"{self.name}: encode_all takes objects with scalar fields only")
            src = (f"def encode_all(_objs):\n    try:\n        return b''.join([_pack({args}) for _o in _objs])\n"
                   f"    except (_StructError, TypeError, OverflowError) as exc:\n"
                   f"        raise ValueError(f'{self.name}: {{exc}}') from exc\n")
            fn = self._compile(src, ns, "encode_all")
            self.bindings.append(Binding(self, cls, "encode_all", mapping, fn, (), dict(fixed)))
            return fn
        if from_args:
            src = f"def encode({', '.join(f.name for f in cls_fields if f.name in by_cls)}):\n"
        else:
            src = "def encode(_o):\n"
        fn = self._compile(src + self._pack_stmt((pre, args)), ns, "encode")
        names = tuple(f.name for f in cls_fields if f.name in by_cls) if from_args else ()
        self.bindings.append(Binding(self, cls, "encode_args" if from_args else "encode", mapping, fn, names,
                                     dict(fixed)))
        return fn
