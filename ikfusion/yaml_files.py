"""Reading the YAML files users write: maps, bodies, readers, tags, heights, sessions, configs.

One reader, so that every such file fails the same way: anything that does not hold is a
:class:`~ikfusion.errors.ConfigError` (exit code 2) naming the file and the line. What a user
file may hold:

- **Text**: UTF-8, with or without a byte-order mark, or UTF-16 / UTF-32 with a byte-order mark
  (what Windows editors write when asked for "Unicode"). Any other byte (e.g. Latin-1 ``é``) is
  refused with its line, column and byte offset: we never guess an encoding.
- **Keys**: each key at most once per mapping. YAML itself keeps the last of two equal keys
  silently (a second ``height`` moved a head by 15 cm); here the second one is an error naming
  both lines. Merge keys (``<<: *base``) may still be overridden by the mapping's own keys.
- **Anchors and aliases** (``&name`` / ``*name``): none of the shipped configs uses them, but a
  hand-written file may reuse a block. What the aliases expand to is bounded: at most
  :data:`MAX_ALIAS_NODES` nodes beyond those written in the file (counted with every alias
  expanded), and an alias may not sit inside its own anchor. A "billion laughs" file, a few
  lines that expand to 10^9 values, is refused before anything is built from it.
- **Nesting**: as deep as the parser's recursion allows; deeper is refused, not a crash.
"""

from __future__ import annotations

import codecs
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError

__all__ = ["MAX_ALIAS_NODES", "YamlDocument", "decode_text", "read_yaml", "read_yaml_document",
           "with_line"]

#: Nodes that aliases may add to a document beyond the nodes written in it (each alias counted
#: as the whole node it names). Reusing a block of a few hundred values a few hundred times fits.
MAX_ALIAS_NODES = 100_000

#: Byte-order marks and the codec that reads the text after them (UTF-32 first: its little-endian
#: mark starts like UTF-16's).
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)

_MERGE_TAG = "tag:yaml.org,2002:merge"


@dataclass(frozen=True)
class YamlDocument:
    """A parsed YAML file with the line of each mapping key.

    Attributes:
        data: The parsed content (plain dicts, lists and scalars).
        path: The file.
        lines: Key path (mapping keys and list indices as text, e.g. ``("readers", "0", "id")``)
            -> 1-based line of that key or item.
    """

    data: Any
    path: Path
    lines: dict[tuple[str, ...], int] = field(default_factory=dict)

    def line_of(self, *keys: object) -> int | None:
        """The 1-based line of the key at ``keys`` (e.g. ``line_of("sensors", "00B42279")``)."""
        return self.lines.get(tuple(str(k) for k in keys))


def with_line(err: ConfigError, line: int | None) -> ConfigError:
    """The same error with its line filled in (unchanged when it has one or ``line`` is None)."""
    if err.line is not None or line is None:
        return err
    return ConfigError(err.reason, path=err.path, line=line, field=err.field)


def read_user_file(path: Path, what: str) -> bytes:
    """The bytes of a file the user gave.

    Raises:
        ConfigError: The file cannot be read (missing, a folder, no permission), naming it.
    """
    try:
        return path.read_bytes()
    except OSError as err:
        raise ConfigError(f"cannot read {what}: {err.strerror}", path=path) from err


def decode_text(data: bytes, path: Path) -> str:
    """The text of a user file: UTF-8, or UTF-8/16/32 after a byte-order mark.

    Args:
        data: The file's bytes.
        path: The file, for the message.

    Raises:
        ConfigError: A byte that the encoding cannot read, naming its line, column (character
            in the line) and byte offset in the file.
    """
    encoding = next((codec for bom, codec in _BOMS if data.startswith(bom)), "utf-8")
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        before = data[:err.start].decode(encoding, errors="replace")
        line = before.count("\n") + 1
        column = len(before) - (before.rfind("\n") + 1) + 1
        bad = data[err.start:err.end][:4].hex(" ").upper()
        name = "UTF-8" if encoding == "utf-8" else encoding.upper().replace("-SIG", "")
        raise ConfigError(
            f"not {name} text: byte(s) {bad} at column {column} (byte offset "
            f"{err.start} of the file) cannot be read; save the file as UTF-8 (Latin-1 and other "
            "legacy encodings are not read)", path=path, line=line) from None


def read_yaml(path: str | Path, what: str = "file",
              loader: type[yaml.SafeLoader] = yaml.SafeLoader) -> Any:
    """The parsed content of a YAML file (see the module docstring for what is refused).

    Args:
        path: The file.
        what: What the file is, for the message (``"sensor map"``, ``"tags file"``, ...).
        loader: A ``yaml.SafeLoader`` subclass (e.g. one that keeps ids as text).

    Raises:
        ConfigError: The file cannot be read, is not UTF-8/16/32 text, is not valid YAML, repeats
            a key, or its aliases expand too far; with the line.
    """
    return read_yaml_document(path, what, loader).data


#: Documents parsed before, by (file, modification time [ns], size, loader): a process that
#: reads the same config again (a batch worker, a retarget per clip) parses it once. Kept
#: pickled: unpickling gives each caller its own copy several times faster than ``deepcopy``.
_PARSED: dict[tuple[str, str, int, int, type[yaml.SafeLoader]], bytes] = {}
#: At most this many documents are kept (the oldest goes first).
_PARSED_MAX = 64


def read_yaml_document(path: str | Path, what: str = "file",
                       loader: type[yaml.SafeLoader] = yaml.SafeLoader) -> YamlDocument:
    """Like :func:`read_yaml`, with the line of every mapping key (for messages about values).

    A file unchanged since it was last read (same modification time and size) is not parsed
    again: the caller gets its own copy of the earlier result (unpickled, as deep as a deep copy).

    Raises:
        ConfigError: As :func:`read_yaml`.
    """
    file = Path(path)
    try:
        stat = file.stat()
        key: tuple[str, str, int, int, type[yaml.SafeLoader]] | None = (
            str(file), str(file.absolute()), stat.st_mtime_ns, stat.st_size, loader)
    except OSError:
        key = None  # read_user_file names the problem
    if key is not None and key in _PARSED:
        document: YamlDocument = pickle.loads(_PARSED[key])
        return document
    document = _parse_yaml_document(file, what, loader)
    if key is not None:
        if len(_PARSED) >= _PARSED_MAX:
            del _PARSED[next(iter(_PARSED))]
        _PARSED[key] = pickle.dumps(document, protocol=pickle.HIGHEST_PROTOCOL)
    return document


def _parse_yaml_document(file: Path, what: str,
                         loader: type[yaml.SafeLoader]) -> YamlDocument:
    """Read and parse ``file`` (see :func:`read_yaml_document`)."""
    text = decode_text(read_user_file(file, what), file)
    try:
        parser = loader(text)  # checks the characters
        try:
            node = parser.get_single_node()
            lines = _NodeCheck(parser, file).run(node)
            content = None if node is None else parser.construct_document(node)
        finally:
            parser.dispose()
    except yaml.YAMLError as err:
        raise _yaml_error(err, text, file) from err
    except RecursionError:
        raise ConfigError("the YAML is nested too deeply to read", path=file) from None
    return YamlDocument(content, file, lines)


def _yaml_error(err: yaml.YAMLError, text: str, file: Path) -> ConfigError:
    """A parser error as a ConfigError with the line."""
    if isinstance(err, yaml.reader.ReaderError):
        line = text.count("\n", 0, err.position) + 1
        hint = " (is it UTF-16 without a byte-order mark?)" if err.character == 0 else ""
        return ConfigError(f"not valid YAML: character U+{err.character:04X} is not allowed in "
                           f"YAML text{hint}; save the file as UTF-8", path=file, line=line)
    mark = getattr(err, "problem_mark", None)
    return ConfigError(f"not valid YAML: {getattr(err, 'problem', None) or err}", path=file,
                       line=None if mark is None else mark.line + 1)


class _NodeCheck:
    """One walk over the composed YAML nodes, before any Python object is built from them.

    Refuses repeated keys, aliases inside their own anchor, alias expansion beyond
    :data:`MAX_ALIAS_NODES` and scalars Python cannot hold; records the line of every key. A
    node reached through an alias is walked once (its expanded size is remembered), so the walk
    is linear in the file.
    """

    def __init__(self, parser: yaml.SafeLoader, file: Path) -> None:
        self.parser = parser
        self.file = file
        self.sizes: dict[int, int] = {}
        self.open: set[int] = set()
        self.lines: dict[tuple[str, ...], int] = {}

    def run(self, root: yaml.Node | None) -> dict[tuple[str, ...], int]:
        """Check the document; returns the key lines."""
        if root is None:
            return self.lines
        expanded = self._size(root, ())
        if expanded - len(self.sizes) > MAX_ALIAS_NODES:
            raise ConfigError(
                f"the YAML aliases (*name) expand {len(self.sizes)} written nodes to {expanded}; "
                f"at most {MAX_ALIAS_NODES} more are allowed (an alias 'bomb'); write the values "
                "out or reuse fewer blocks", path=self.file, line=root.start_mark.line + 1)
        return self.lines

    def _size(self, node: yaml.Node, keys: tuple[str, ...]) -> int:
        """Nodes in ``node`` with every alias expanded; checks each mapping on first visit."""
        ident = id(node)
        if ident in self.sizes:
            return self.sizes[ident]
        if ident in self.open:
            raise ConfigError("an alias (*name) refers to the anchor that contains it (a "
                              "recursive structure)", path=self.file,
                              line=self.lines.get(keys, node.start_mark.line + 1),
                              field=".".join(keys) or None)
        self.open.add(ident)
        total = 1
        if isinstance(node, yaml.MappingNode):
            self._refuse_repeated_keys(node, keys)
            for key_node, value_node in node.value:
                key = keys + (str(key_node.value),) if isinstance(key_node, yaml.ScalarNode) \
                    else keys
                self.lines.setdefault(key, key_node.start_mark.line + 1)
                total += self._size(key_node, key) + self._size(value_node, key)
        elif isinstance(node, yaml.ScalarNode) and node.tag != _MERGE_TAG:
            self._construct_scalar(node, keys)
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                key = keys + (str(index),)
                self.lines.setdefault(key, item.start_mark.line + 1)
                total += self._size(item, key)
        self.open.discard(ident)
        self.sizes[ident] = total
        return total

    def _construct_scalar(self, node: yaml.ScalarNode, keys: tuple[str, ...]) -> None:
        """Build a scalar now (the parser keeps it for the document).

        So a value Python cannot hold (an integer of 5000 digits, the date 2001-13-45) is refused
        with its line.
        """
        try:
            self.parser.construct_object(node)
        except (ValueError, OverflowError) as err:
            raise ConfigError(f"cannot read the value {node.value[:40]!r}: {err}", path=self.file,
                              line=node.start_mark.line + 1,
                              field=".".join(keys) or None) from None

    def _refuse_repeated_keys(self, node: yaml.MappingNode, keys: tuple[str, ...]) -> None:
        """Refuse two equal scalar keys in one mapping.

        Keys compare as loaded: ``1`` and ``01`` are equal ints, ``"1"`` and ``1`` differ.
        """
        seen: dict[Any, tuple[int, yaml.Node]] = {}
        for index, (key_node, _) in enumerate(node.value):
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE_TAG:
                continue
            key = self.parser.construct_object(key_node)
            try:
                first_index, first = seen.setdefault(key, (index, key_node))
            except TypeError:  # not hashable: the constructor reports it
                continue
            if first_index != index:
                line = key_node.start_mark.line + 1
                raise ConfigError(
                    f"key {key!s} appears twice in the same mapping (lines "
                    f"{first.start_mark.line + 1} and {line}); YAML would silently keep the last "
                    "one: remove one", path=self.file, line=line,
                    field=".".join((*keys, str(key))))
