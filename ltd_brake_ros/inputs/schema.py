"""What every input file shares: errors, where files are found, YAML parsing, field checks.

Every file is validated once, at load, into immutable dataclasses whose field names carry their
units. Bad input raises :class:`InputError` naming the file, the field path and the reason.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import os
import re
import stat
import sys
import threading
import time
import unicodedata
from pathlib import Path
from typing import Any, Mapping

import yaml
from yaml.composer import Composer
from yaml.constructor import ConstructorError, SafeConstructor
from yaml.events import AliasEvent
from yaml.nodes import CollectionNode, ScalarNode, SequenceNode
from yaml.resolver import BaseResolver

from ..physics.parameters import out_of_range, specs


class InputError(ValueError):
    """A bad input file or value.

    Parameters
    ----------
    source : str
        File (or topic / parameter) the value came from.
    field : str
        Path of the offending field, e.g. ``vehicles[3].mass_t``; empty for the whole file.
    reason : str
        What is wrong, in words a user can act on.

    Examples
    --------
    >>> from ltd_brake_ros import InputError, load_consist
    >>> try:
    ...     load_consist("scenario_99")
    ... except InputError as exc:
    ...     print(exc.source)  # doctest: +SKIP
    """

    def __init__(self, source: str, field: str, reason: str):
        self.source, self.field, self.reason = str(source), field, reason
        where = f"{self.source}: {field}" if field else self.source
        super().__init__(f"{where}: {reason}")


# --------------------------------------------------------------------------- config location


def config_dir() -> Path:
    """Directory of the shipped configuration files.

    Returns
    -------
    pathlib.Path
        The first of: ``$LTD_BRAKE_CONFIG``, the source checkout's ``config/``, the installed
        ``share/ltd_brake_ros/config`` (pip or colcon prefix).
    """
    env = os.environ.get("LTD_BRAKE_CONFIG") or ""
    first = _FIRST_CHOICE.get(env)
    if first is not None and os.path.isfile(first[1]):
        return first[0]  # found before, and nothing comes before it
    candidates = []
    if env:
        candidates.append(Path(env))
    candidates.append(_checkout_config())
    candidates.append(Path(sys.prefix) / "share" / "ltd_brake_ros" / "config")
    for k, path in enumerate(candidates):
        if (path / "scenarios.yaml").is_file():
            if k == 0:
                _FIRST_CHOICE[env] = (path, os.path.join(path, "scenarios.yaml"))
            return path
    try:  # colcon / ROS install space
        from ament_index_python.packages import get_package_share_directory

        path = Path(get_package_share_directory("ltd_brake_ros")) / "config"
        if path.is_dir():
            return path
    except Exception:  # noqa: BLE001 - ament index absent or package not registered
        pass
    raise InputError("config", "", "cannot find the shipped config/ directory; set LTD_BRAKE_CONFIG")


#: ``$LTD_BRAKE_CONFIG`` -> the config directory found as the first candidate for it, and its
#: scenario catalogue (checked on every call: while it exists, no other candidate can win).
_FIRST_CHOICE: dict[str, tuple[Path, str]] = {}


@functools.lru_cache(maxsize=1)
def _checkout_config() -> Path:
    """``config/`` of the source checkout this module lies in (whether or not it exists)."""
    return Path(__file__).resolve().parents[2] / "config"


def resolve_config_path(path: str | os.PathLike, base: Path | None = None) -> Path:
    """Resolve a file name against the working directory, ``base`` and the shipped config.

    Parameters
    ----------
    path : str or path-like
        Absolute path, path relative to the working directory or to ``base``, or a path
        relative to the shipped ``config/`` directory (e.g. ``couplers/buffer_hook_pugi.yaml``).
    base : pathlib.Path, optional
        Directory of the file that refers to ``path``.

    Returns
    -------
    pathlib.Path
        An existing file; if none exists, ``path`` unchanged so that loading names it.
    """
    # os.path on strings: pathlib costs more than the file system here
    p = os.path.expanduser(os.fspath(path))
    if os.path.isabs(p):
        return _path(p)
    for root in ([base] if base else []) + [os.getcwd(), config_dir()]:
        candidate = os.path.join(root, p)
        if os.path.isfile(candidate):
            return _path(candidate)
    return _path(p)


@functools.lru_cache(maxsize=256)
def _path(text: str) -> Path:
    """``Path(text)``, parsed once (paths are immutable)."""
    return Path(text)


#: Largest input file read [bytes]; the biggest consist (5000 vehicles, one line each) is < 1 MiB.
MAX_FILE_BYTES = 8 * 2**20
#: Deepest nesting of lists and mappings accepted; input files need about 5 levels.
MAX_DEPTH = 32
#: Most values (scalars, lists and mappings, each use of an alias counted as a copy of what it
#: refers to) a file may hold: five times the biggest consist written out vehicle by vehicle.
MAX_NODES = 500_000


def load_yaml(path: str | os.PathLike) -> Any:
    """Parse a YAML input file into what a person reads in it, within fixed bounds.

    Plain scalars are read with the YAML 1.2 core schema: whole numbers are decimal (``050``
    is 50, not octal 40), ``1.5e3`` is a number, ``1:20``, ``1_000``, ``0x10`` and ``yes``/``no``/
    ``on``/``off`` are text (YAML 1.1 read them as 80, 1000, 16 and booleans); only ``true``
    and ``false`` are booleans. Explicit tags outside that schema (``!!timestamp``, ``!!binary``,
    ``!!set``, Python tags) are refused. A key given twice in one mapping is refused.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    InputError
        The file cannot be read, is not YAML, has a duplicate key, or exceeds
        :data:`MAX_FILE_BYTES`, :data:`MAX_DEPTH` or :data:`MAX_NODES` (which bounds what
        aliases can expand to); one line naming the file, the field and the line.
    """
    p = Path(path)
    return parse_yaml(read_input(p), p)


def read_input(path: str | os.PathLike) -> bytes:
    """The bytes of an input file, with the checks of :func:`load_yaml`.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    bytes

    Raises
    ------
    InputError
        The file does not exist, is not a regular file, cannot be read or is larger than
        :data:`MAX_FILE_BYTES`.
    """
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        raise InputError(Path(path), "", "file does not exist") from None
    except OSError as exc:
        raise InputError(Path(path), "", f"cannot read: {exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(Path(path), "", "is not a regular file")
    name = os.fspath(path)
    known = _READ.get(name)
    if known is not None and known[0] == _signature(st):
        return known[1]
    try:
        with open(path, "rb") as fh:
            st = os.fstat(fh.fileno())
            # what the file holds and a byte more (reading into a buffer of the largest size
            # allowed costs more than the read), on to that size if it grew meanwhile
            raw = fh.read(min(st.st_size, MAX_FILE_BYTES) + 1)
            if st.st_size < len(raw) <= MAX_FILE_BYTES:
                raw += fh.read(MAX_FILE_BYTES + 1 - len(raw))
    except OSError as exc:
        raise InputError(Path(path), "", f"cannot read: {exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise InputError(Path(path), "", f"is larger than {MAX_FILE_BYTES // 2**20} MiB; "
                         f"input files are limited to {MAX_FILE_BYTES // 2**20} MiB")
    # kept only when the file had not changed for a while before it was opened: any later
    # change then gives it a newer change time (ctime, which no program can set back)
    if len(raw) <= _KEPT_BYTES and time.time_ns() - st.st_ctime_ns > _SETTLED_NS:
        with _READ_LOCK:
            _READ[name] = (_signature(st), raw)
            while len(_READ) > _KEPT_FILES:
                del _READ[next(iter(_READ))]
    return raw


def _signature(st: os.stat_result) -> tuple:
    """What changes when a file is written, replaced or touched."""
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


#: Files read by :func:`read_input`, by name: their :func:`_signature` and bytes, reused
#: while the signature holds.
_READ: dict[str, tuple[tuple, bytes]] = {}
_READ_LOCK = threading.Lock()
#: A file is kept once it has not changed for this long [ns]: longer than the coarsest
#: time stamps of a file system (2 s on FAT), so that a change after the read cannot leave
#: the change time as it was.
_SETTLED_NS = 3 * 10**9
#: Most files kept, and the largest kept [bytes].
_KEPT_FILES, _KEPT_BYTES = 32, 2**20


#: Byte-order marks of encodings an input file may not use, and their names.
_OTHER_BOMS = ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
               (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16"))


def decode_text(raw: bytes, source: str | os.PathLike) -> str:
    """The text of an input file: UTF-8 (a byte-order mark is allowed), nothing else.

    Parameters
    ----------
    raw : bytes
    source : str or path-like
        The file, for error messages.

    Returns
    -------
    str

    Raises
    ------
    InputError
        One line: a UTF-16/32 file, a binary file, or bytes that are not UTF-8 (with where).
    """
    for bom, name in _OTHER_BOMS:
        if raw.startswith(bom):
            raise InputError(source, "", f"is {name} text; save it as UTF-8")
    nul = raw.find(b"\x00", 0, 4096)
    if nul >= 0:
        raise InputError(source, "", f"is a binary file, not text (a NUL byte at offset {nul}); "
                         "is it the right file?")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(source, "", f"is not UTF-8 text (byte 0x{raw[exc.start]:02X} on line "
                         f"{line}; Latin-1 or Windows-1252?): save it as UTF-8") from None


def parse_yaml(raw: bytes, source: str | os.PathLike) -> Any:
    """Parse the bytes of a YAML input file as :func:`load_yaml` does.

    Parameters
    ----------
    raw : bytes
        The file's contents (:func:`read_input`).
    source : str or path-like
        The file, for error messages.

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    InputError
        As :func:`load_yaml`.
    """
    text = decode_text(raw, source)
    data = _load_plain(text)
    if data is not _NOT_PLAIN:
        return data
    loader = _Loader(text)
    try:
        return loader.get_single_data()
    except _Refused as exc:
        raise InputError(source, exc.field, exc.reason) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(source, "", f"not valid YAML{where}: {problem}") from None
    finally:
        loader.dispose()


def load_once(path: str | os.PathLike, build, *args) -> Any:
    """``build(document, source, *args)`` of a YAML input file, built once per contents.

    The file's bytes come from :func:`read_input` (read again whenever its device, inode,
    size, modification or change time differ) and the value is built again whenever those
    bytes (or ``args``) differ from those of a value already built, so an edited file is
    never served from before the edit.

    Parameters
    ----------
    path : str or path-like
        The file.
    build : callable
        ``build(document, source, *args)`` validates the parsed document into an immutable
        value (shared by every caller).
    *args
        Further arguments of ``build`` (hashable).

    Returns
    -------
    object
        What ``build`` returns.

    Raises
    ------
    InputError
        As :func:`load_yaml`, or as ``build``.
    """
    return built_once(build, str(path), read_input(path), *args)


def built_once(build, source: str, raw: bytes, *args) -> Any:
    """``build(document, source, *args)`` of the bytes ``raw`` of file ``source``, built once
    per (``build``, ``source``, ``raw``, ``args``): :func:`load_once` for a file already read.

    Parameters
    ----------
    build : callable
    source : str
    raw : bytes
    *args
        Hashable.

    Returns
    -------
    object
    """
    return _built(build, source, raw, args)


@functools.lru_cache(maxsize=32)
def _built(build, source: str, raw: bytes, args: tuple) -> Any:
    return build(parse_yaml(raw, source), source, *args)


def decimal_or_text(text: str) -> Any:
    """A text cell (e.g. of a CSV file) read as :func:`load_yaml` reads a plain scalar.

    Parameters
    ----------
    text : str

    Returns
    -------
    float or str
        The number when the text is a decimal number (``12``, ``-0.5``, ``1e3``, ``.inf``),
        else the text stripped (``1:20``, ``1_000`` and ``12 t`` stay text).
    """
    text = text.strip()
    if not (_INT.match(text) or _FLOAT.match(text)):
        return text
    low = text.lower()
    if low.endswith(".inf"):
        return -math.inf if low.startswith("-") else math.inf
    return math.nan if low == ".nan" else float(text)


class _Refused(Exception):
    """A document the loader will not build (field path, reason)."""

    def __init__(self, field: str, reason: str):
        super().__init__(reason)
        self.field, self.reason = field, reason


# YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution)
_INT = re.compile(r"[-+]?[0-9]+\Z")
_FLOAT = re.compile(r"(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))\Z")
_BOOL = re.compile(r"(?:true|True|TRUE|false|False|FALSE)\Z")
_NULL = re.compile(r"(?:~|null|Null|NULL|)\Z")
_TAG = "tag:yaml.org,2002:"

try:  # libyaml parses about three times faster (and composes plain documents: _load_plain)
    from yaml._yaml import CParser as _CParser
except ImportError:  # pragma: no cover - PyYAML built without libyaml
    _CParser = None

if _CParser is not None:
    _Parser = _CParser

    def _init_parser(loader, text):
        _Parser.__init__(loader, text)
else:  # pragma: no cover
    from yaml.parser import Parser as _PyParser
    from yaml.reader import Reader
    from yaml.scanner import Scanner

    class _Parser(Reader, Scanner, _PyParser):
        """PyYAML's pure-Python parser."""

    def _init_parser(loader, text):
        Reader.__init__(loader, text)
        Scanner.__init__(loader)
        _PyParser.__init__(loader)


def _decimal_int(text: str) -> int:
    """A whole number written in decimal (ValueError otherwise, or beyond Python's digits)."""
    if not _INT.fullmatch(text):
        raise ValueError(text)
    return int(text, 10)


def _decimal_float(text: str) -> Any:
    """A number written in decimal, .inf or .nan (ValueError otherwise)."""
    if not _FLOAT.fullmatch(text):
        raise ValueError(text)
    return decimal_or_text(text)


def _core_bool(text: str) -> bool:
    """true or false (ValueError otherwise)."""
    if not _BOOL.fullmatch(text):
        raise ValueError(text)
    return text.lower() == "true"


class _Loader(_Parser, Composer, SafeConstructor, BaseResolver):
    """PyYAML loader with the core schema, duplicate-key refusal and bounds (see load_yaml)."""

    yaml_implicit_resolvers: dict = {}
    yaml_constructors: dict = {}

    def __init__(self, text: str):
        _init_parser(self, text)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        BaseResolver.__init__(self)
        self._path: list[str] = []  # field path of the node being composed
        self._sizes: dict[int, int] = {}  # id of a complete list/mapping node -> values in it

    # the Python composer (bounded, checks duplicates), not libyaml's
    get_single_node = Composer.get_single_node
    get_single_data = SafeConstructor.get_single_data

    def _where(self) -> str:
        """Field path of the node being composed, e.g. ``vehicles[3].brake``."""
        out = ""
        for part in filter(None, self._path):
            out += part if part.startswith("[") or not out else "." + part
        return out

    def compose_node(self, parent, index):
        mark = self.peek_event().start_mark
        if isinstance(parent, SequenceNode):
            self._path.append(f"[{index}]")
        elif isinstance(index, ScalarNode):
            self._path.append(str(index.value))
        elif index is not None:
            self._path.append("?")
        else:
            self._path.append("")  # a mapping key, or the root
        try:
            if len(self._path) > MAX_DEPTH + 1:
                top = next(filter(None, self._path), "")
                raise _Refused(top, f"nested deeper than {MAX_DEPTH} levels (line "
                               f"{mark.line + 1}); input files need fewer than 10")
            alias = self.check_event(AliasEvent)
            node = super().compose_node(parent, index)
            if not isinstance(node, CollectionNode) or id(node) in self._sizes:
                return node  # a scalar, or a complete node an alias refers to
            if alias:
                raise _Refused(self._where(), f"the alias on line {mark.line + 1} refers to a "
                               "list or mapping that contains it")
            items = node.value if isinstance(node, SequenceNode) else \
                [n for pair in node.value for n in pair]
            size = 1 + sum(self._sizes.get(id(n), 1) for n in items)
            if size > MAX_NODES:
                raise _Refused(self._where(), f"holds more than {MAX_NODES} values, counting "
                               "every use of an alias (*name) as a copy (line "
                               f"{mark.line + 1}); input files hold far fewer")
            self._sizes[id(node)] = size
            return node
        finally:
            self._path.pop()

    def compose_mapping_node(self, anchor):
        node = super().compose_mapping_node(anchor)
        seen: dict = {}
        for key, _value in node.value:
            if not isinstance(key, ScalarNode):
                continue
            same = (key.tag, _key_value(key))
            if same in seen:
                first, second = seen[same].start_mark.line + 1, key.start_mark.line + 1
                lines = f"on line {first}" if first == second else \
                    f"(line {first} and line {second})"
                self._path.append(str(key.value))
                where = self._where()
                self._path.pop()
                raise _Refused(where, f"given twice {lines}; a key may appear once")
            seen[same] = key
        return node

    def _scalar(self, node, read, what: str):
        """The value ``read`` makes of a scalar's text, or the error naming ``what``."""
        value = self.construct_scalar(node)
        try:
            return read(value)
        except ValueError:
            raise ConstructorError(None, None, f"cannot read {value!r} as {what}",
                                   node.start_mark) from None

    def construct_decimal_int(self, node):
        """A whole number written in decimal."""
        return self._scalar(node, _decimal_int, "a decimal whole number")

    def construct_decimal_float(self, node):
        """A number written in decimal, .inf or .nan."""
        return self._scalar(node, _decimal_float, "a decimal number")

    def construct_core_bool(self, node):
        """true or false."""
        return self._scalar(node, _core_bool, "true or false")


def _key_value(node) -> Any:
    """A scalar key as the value it stands for (``06`` and ``6`` are the same key)."""
    text = node.value
    if node.tag == _TAG + "int" and _INT.fullmatch(text):
        return int(text, 10)
    if node.tag == _TAG + "float" and _FLOAT.fullmatch(text) and not text.lower().endswith(
            (".inf", ".nan")):
        return float(text)
    if node.tag == _TAG + "bool":
        return text.lower()
    if node.tag == _TAG + "null":
        return None
    return text


for _tag, _regex, _first in (("bool", _BOOL, "tTfF"), ("int", _INT, "-+0123456789"),
                             ("float", _FLOAT, "-+0123456789."), ("null", _NULL, "~nN")):
    _Loader.add_implicit_resolver(_TAG + _tag, _regex, list(_first))
_Loader.add_implicit_resolver(_TAG + "null", _NULL, [""])
for _tag, _constructor in (
        ("str", SafeConstructor.construct_yaml_str),
        ("seq", SafeConstructor.construct_yaml_seq),
        ("map", SafeConstructor.construct_yaml_map),
        ("null", SafeConstructor.construct_yaml_null),
        ("bool", _Loader.construct_core_bool),
        ("int", _Loader.construct_decimal_int),
        ("float", _Loader.construct_decimal_float)):
    _Loader.add_constructor(_TAG + _tag, _constructor)
_Loader.add_constructor(None, SafeConstructor.construct_undefined)


#: Most structure indicators (``[{-:?``, each able to open one level) in a text that libyaml's
#: composer may read: it recurses in C without a bound, about 0.5 kB of stack a level.
_C_COMPOSER_INDICATORS = 1000
#: What :func:`_load_plain` returns for a document that :class:`_Loader` must read.
_NOT_PLAIN = object()


def _load_plain(text: str) -> Any:
    """A plain document read by libyaml's composer, else :data:`_NOT_PLAIN`.

    Plain: shallow enough for the C composer (:data:`_C_COMPOSER_INDICATORS`), valid YAML, a
    tree (no alias to a list or mapping), within :data:`MAX_DEPTH` and :data:`MAX_NODES`, with
    text, number, boolean or null keys given once per mapping, and only the tags of the core
    schema. Such a document composes into the nodes the Python composer of :class:`_Loader`
    builds (the same parser events and resolver), none of whose refusals apply, and
    :func:`_plain_data` builds from them what :class:`_Loader`'s constructors build; anything
    else, error or doubt, is left to :class:`_Loader`, which reads it (or words the error) as
    always.
    """
    if _CParser is None or sum(map(text.count, "[{-:?")) > _C_COMPOSER_INDICATORS:
        return _NOT_PLAIN
    loader = _PlainLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        return _plain_data(node) if _plain_tree(node) else _NOT_PLAIN
    except Exception:  # noqa: BLE001 - _Loader reads it again and words the error
        return _NOT_PLAIN
    finally:
        loader.dispose()


def _plain_tree(root) -> bool:
    """True when a composed document is one that :class:`_Loader` composes without refusal
    (see :func:`_load_plain`)."""
    seen: set[int] = set()  # collections met, to find one reached twice (an alias)
    stack = [(root, 1)]  # node, depth (the root's is 1)
    count = 0
    while stack:
        node, depth = stack.pop()
        count += 1
        if depth > MAX_DEPTH + 1 or count > MAX_NODES:
            return False
        if isinstance(node, ScalarNode):
            continue
        if id(node) in seen:
            return False
        seen.add(id(node))
        if isinstance(node, SequenceNode):
            stack.extend((item, depth + 1) for item in node.value)
            continue
        keys = set()
        for key, value in node.value:
            if not isinstance(key, ScalarNode):
                return False
            same = (key.tag, _key_value(key))
            if same in keys:
                return False
            keys.add(same)
            stack.append((key, depth + 1))
            stack.append((value, depth + 1))
    return True


def _plain_data(node) -> Any:
    """The data of a node of a plain tree (see :func:`_load_plain`), as :class:`_Loader`'s
    constructors build it; raises for a value they refuse."""
    if isinstance(node, ScalarNode):
        return _PLAIN_SCALARS[node.tag](node.value)
    if node.tag == _TAG + "seq":
        return [_plain_data(item) for item in node.value]
    if node.tag == _TAG + "map":
        return {_plain_data(key): _plain_data(value) for key, value in node.value}
    raise KeyError(node.tag)


#: Value of a scalar of each core-schema tag.
_PLAIN_SCALARS = {_TAG + "str": str, _TAG + "null": lambda text: None,
                  _TAG + "bool": _core_bool, _TAG + "int": _decimal_int,
                  _TAG + "float": _decimal_float}

if _CParser is not None:
    class _PlainLoader(_CParser, BaseResolver):
        """libyaml's parser and composer with the resolvers of :class:`_Loader` (see
        :func:`_load_plain`)."""

        yaml_implicit_resolvers = _Loader.yaml_implicit_resolvers

        def __init__(self, text: str):
            _CParser.__init__(self, text)
            BaseResolver.__init__(self)


# --------------------------------------------------------------------------- field readers


#: Longest text of an input: a name, a description, a source [characters].
TEXT_MAX_CHARS = 200
#: Longest file name an input may give under one of :data:`PATH_KEYS` [characters].
PATH_MAX_CHARS = 4096
#: Keys whose values are file names rather than names.
PATH_KEYS = frozenset({"file"})


def text_problem(text: str, max_chars: int = TEXT_MAX_CHARS) -> str | None:
    """What makes ``text`` unfit as a name or description of an input, or None.

    Text is printable Unicode (letters, marks, numbers, punctuation, symbols and spaces; the
    characters markup uses are ordinary text) without control, format or private-use
    characters and line breaks, and at most ``max_chars`` characters long.

    Parameters
    ----------
    text : str
    max_chars : int, optional

    Returns
    -------
    str or None
        The reason, in words a user can act on.
    """
    if len(text) > max_chars:
        return f"is {len(text)} characters long; at most {max_chars}"
    for i, c in enumerate(text):
        category = unicodedata.category(c)
        if category[0] == "C" or category in ("Zl", "Zp"):
            what = "a control character" if category == "Cc" else "an unprintable character"
            return (f"contains {what} (U+{ord(c):04X}, character {i + 1}); names and "
                    "descriptions are printable text on one line")
    return None


def _shown(text: str) -> str:
    """``text`` quoted for a one-line message: escaped and cut to 40 characters."""
    return repr(text[:40]) + ("..." if len(text) > 40 else "")


def check_texts(data: Any, source: str, path: str = "") -> None:
    """Refuse the first text of a document (a key or a value, at any depth) that
    :func:`text_problem` refuses, naming its field.

    Parameters
    ----------
    data : object
        A parsed document or a mapping given in its place.
    source : str
        Where it came from.
    path : str, optional
        Its path in the file.

    Raises
    ------
    InputError
    """
    stack = [(data, path, False)]
    while stack:
        value, where, is_path = stack.pop()
        if isinstance(value, str):
            problem = text_problem(value, PATH_MAX_CHARS if is_path else TEXT_MAX_CHARS)
            if problem:
                raise InputError(source, where, problem)
        elif isinstance(value, Mapping):
            for key, item in value.items():
                if isinstance(key, str):
                    problem = text_problem(key)
                    if problem:
                        raise InputError(source, where, f"the key {_shown(key)} {problem}")
                sub = f"{where}.{key}" if where else str(key)
                stack.append((item, sub, key in PATH_KEYS))
        elif isinstance(value, (list, tuple)):
            stack.extend((item, f"{where}[{i}]", is_path) for i, item in enumerate(value))


class Fields:
    """Typed access to a mapping, raising :class:`InputError` with the field path.

    A document's top mapping (``path`` empty) has every text in it checked first
    (:func:`check_texts`): names, descriptions and keys are bounded printable text.

    Parameters
    ----------
    data : mapping
        The values.
    source : str
        File (or topic) they came from.
    path : str, optional
        Path of the mapping inside the file, e.g. ``vehicles[3]``.
    """

    def __init__(self, data: Any, source: str, path: str = ""):
        if data is None and not path:
            raise InputError(source, "", "is empty")
        if not isinstance(data, Mapping):
            raise InputError(source, path, f"must be a mapping, got {kind_of(data)}")
        if not path:
            check_texts(data, source)
        self.data, self.source, self.path = data, source, path

    def sub(self, name: str) -> str:
        """Path of field ``name``."""
        return f"{self.path}.{name}" if self.path else name

    def error(self, name: str, reason: str) -> InputError:
        """The error for field ``name``."""
        return InputError(self.source, self.sub(name), reason)

    def has(self, name: str) -> bool:
        """Field ``name`` is given (and not null)."""
        return name in self.data and self.data[name] is not None

    def number(self, name: str, default: float | None = None, *, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False) -> float:
        """A finite number within [lo, hi] (``lo`` excluded with ``lo_open``)."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required number)")
            return float(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(name, f"must be a number, got {kind_of(value)} {value!r}"
                             f"{_hint(value)}")
        value = float(value)
        reason = out_of_range(value, lo, hi, lo_open)
        if reason:
            raise self.error(name, reason)
        return value

    def integer(self, name: str, default: int | None = None, *, lo: int = 0,
                hi: int | None = None) -> int:
        """A whole number within [lo, hi]."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required whole number)")
            return int(default)
        value = self.data[name]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"must be a whole number, got {kind_of(value)} {value!r}"
                             f"{_hint(value)}")
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f">= {lo}"
            raise self.error(name, f"must be {bound}, got {value}")
        return value

    def boolean(self, name: str, default: bool) -> bool:
        """true or false."""
        if not self.has(name):
            return default
        value = self.data[name]
        if not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {kind_of(value)} {value!r}"
                             f"{_hint(value, boolean=True)}")
        return value

    def string(self, name: str, default: str | None = None,
               choices: tuple[str, ...] | None = None) -> str:
        """Text, one of ``choices`` when given."""
        if not self.has(name):
            if default is None:
                raise self.error(name, "missing (required text)")
            return default
        value = self.data[name]
        if not isinstance(value, str):
            raise self.error(name, f"must be text, got {kind_of(value)} {value!r}")
        if choices and value not in choices:
            raise self.error(name, f"unknown value {value!r}; expected one of {', '.join(choices)}")
        return value

    def numbers(self, name: str) -> list[float]:
        """A list of finite numbers."""
        if not self.has(name):
            raise self.error(name, "missing (required list of numbers)")
        values = self.data[name]
        if not isinstance(values, list):
            raise self.error(name, f"must be a list of numbers, got {kind_of(values)}")
        out = []
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(self.source, f"{self.sub(name)}[{i}]",
                                 f"must be a finite number, got {v!r}{_hint(v)}")
            out.append(float(v))
        return out

    def reject_unknown(self, allowed: set[str]) -> None:
        """Raise for the first field not in ``allowed``."""
        for key in self.data:
            if key not in allowed:
                raise self.error(str(key), f"unknown field; expected one of {', '.join(sorted(allowed))}")


#: Text that YAML 1.1 read as a number (1:20, 1_000, 0x10, 0o10) or with a unit ("12 t").
_NUMBER_LIKE = re.compile(r"[-+]?\.?[0-9]")
#: Text that YAML 1.1 read as a boolean.
_BOOLEAN_LIKE = {"yes", "no", "on", "off", "y", "n"}


def _hint(value: Any, boolean: bool = False) -> str:
    """How to write the number (or with ``boolean``, the true/false) that ``value`` was
    meant to be, when it was read as text; empty otherwise."""
    if not isinstance(value, str):
        return ""
    if boolean:
        return " (write true or false)" if value.strip().lower() in _BOOLEAN_LIKE else ""
    return " (write a plain decimal number)" if _NUMBER_LIKE.match(value.strip()) else ""


def kind_of(value: Any) -> str:
    """How a value reads in an error message ("text", "a list", ...)."""
    return {type(None): "nothing", bool: "true/false", str: "text", list: "a list",
            dict: "a mapping"}.get(type(value), type(value).__name__)


def params_from_fields(params_type, f: Fields, **fixed):
    """Build a model's ``Params`` from the fields it declares.

    Each field declared with :func:`~ltd_brake_ros.physics.parameters.parameter` is read under
    its file name, checked against its range and scaled to the field's unit; missing fields take
    their defaults. The model's own preconditions are checked when it is compiled.

    Parameters
    ----------
    params_type : type
        A model's ``Params`` dataclass.
    f : Fields
        The mapping to read.
    **fixed
        Values of fields that do not come from the mapping (e.g. ``source``).

    Returns
    -------
    params_type
    """
    values = {}
    for name, spec in specs(params_type).items():
        key = spec.key or name
        default = params_type.__dataclass_fields__[name].default
        if isinstance(default, bool):
            values[name] = f.boolean(key, default)
            continue
        if spec.sequence:  # a required table column (its range is the model's to check)
            values[name] = tuple(spec.scale * x for x in f.numbers(key))
            continue
        if default is dataclasses.MISSING:
            default = None
        elif spec.scale != 1.0:
            default = default / spec.scale
        values[name] = spec.scale * f.number(key, default, lo=spec.lo, hi=spec.hi,
                                             lo_open=spec.lo_open)
    return params_type(**values, **fixed)


def file_keys(params_type) -> set[str]:
    """Names a file may use for the fields of a model's ``Params``."""
    return {spec.key or name for name, spec in specs(params_type).items()}
