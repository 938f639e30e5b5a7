"""A Simulink file's bytes to its XML parts or its text, each checked before it is read.

- ``.slx`` is a zip (an OPC package). Every member is checked from the zip's directory before
  any is read: how many there are, their names (no absolute path, no ``..``, no drive, no NUL),
  their declared sizes, the total, and the compression ratio (a zip bomb declares gigabytes from
  kilobytes); then only the XML parts the reader needs are read, each through a bounded read (a
  member that inflates past its declared size is refused too).
- A ``.mdl`` is text: classic sections, or a text package (``__MWOPC_PACKAGE_BEGIN__``) whose
  parts are the same XML as an ``.slx``'s (a ``BASE64`` part is binary and is not read).
- XML is parsed by defusedxml (the standard of the field): a DTD, an entity declaration or an
  external reference is refused before anything is expanded or fetched; the depth of elements
  and their count are bounded as each element opens.

Every failure is a :class:`ContainerError` with one sentence: the caller names the file.
"""

from __future__ import annotations

import io
import re
import zipfile
from xml.etree import ElementTree

from odelab.formats.simulink.tree import MAX_NODES, Node, TreeError, from_xml

__all__ = ["MAX_MEMBERS", "MAX_MEMBER_BYTES", "MAX_TOTAL_BYTES", "MAX_RATIO", "MAX_XML_DEPTH", "ContainerError",
           "parse_xml", "read_package", "split_text_package"]

MAX_MEMBERS = 10_000
"""An ``.slx`` holds at most 10,000 members (a model with 500 subsystems has about 540)."""
MAX_MEMBER_BYTES = 64_000_000
"""A member inflates to at most 64 MB."""
MAX_TOTAL_BYTES = 256_000_000
"""All members together inflate to at most 256 MB."""
MAX_RATIO = 200
"""A member larger than 1 MB inflates at most 200 times its compressed size (XML compresses 10-30 times;
a zip bomb thousands of times)."""
MAX_XML_DEPTH = 512
"""XML elements nest at most 512 deep."""


class ContainerError(ValueError):
    """A file refused before its model is read; ``depth`` when it was the nesting of subsystems."""

    def __init__(self, message: str, depth: bool = False):
        super().__init__(message)
        self.depth = depth


_SAFE_NAME = re.compile(r"^[A-Za-z0-9_\-. /\[\]%()+~]+$")


def _check_name(name: str) -> None:
    parts = name.replace("\\", "/").split("/")
    if (not name or "\x00" in name or name.startswith(("/", "\\")) or ".." in parts or re.match(r"^[A-Za-z]:", name)
            or not _SAFE_NAME.match(name)):
        raise ContainerError(f"its zip member {name!r} has a name no model has (an absolute path, `..` or a drive); "
                             "the file is refused, nothing was extracted")


def _member_budget(infos) -> None:
    if len(infos) > MAX_MEMBERS:
        raise ContainerError(f"it is a zip of {len(infos):,} members; a model has at most {MAX_MEMBERS:,}")
    total = 0
    for info in infos:
        _check_name(info.filename)
        if info.flag_bits & 0x1:
            raise ContainerError(f"its zip member {info.filename!r} is encrypted; save the model again without "
                                 "a password")
        if info.file_size > MAX_MEMBER_BYTES:
            raise ContainerError(f"its zip member {info.filename!r} inflates to {info.file_size:,} bytes; members are "
                                 f"limited to {MAX_MEMBER_BYTES:,} bytes")
        if info.file_size > 1_000_000 and info.file_size > MAX_RATIO * max(info.compress_size, 1):
            raise ContainerError(f"its zip member {info.filename!r} inflates {info.file_size / max(info.compress_size, 1):,.0f} "
                                 f"times ({info.compress_size:,} -> {info.file_size:,} bytes): a zip bomb, not a model "
                                 f"(the limit is {MAX_RATIO} times)")
        total += info.file_size
        if total > MAX_TOTAL_BYTES:
            raise ContainerError(f"its zip members inflate to more than {MAX_TOTAL_BYTES:,} bytes together; a model "
                                 "is far smaller")


def _wanted(name: str) -> bool:
    name = name.lower()
    return name.endswith(".xml") and (name.startswith("simulink/") or name == "metadata/coreproperties.xml")


def read_package(raw: bytes) -> dict[str, bytes]:
    """The XML parts of an ``.slx`` under ``simulink/`` (lower-case names), every member checked first."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(raw))
        infos = zf.infolist()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ContainerError(f"it is not a readable zip (an .slx is one): {exc}") from None
    _member_budget(infos)
    parts: dict[str, bytes] = {}
    for info in infos:
        if info.is_dir() or not _wanted(info.filename):
            continue
        try:
            with zf.open(info) as fh:
                data = fh.read(info.file_size + 1)
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError, RuntimeError) as exc:
            raise ContainerError(f"its zip member {info.filename!r} cannot be read: {exc}") from None
        if len(data) > info.file_size:
            raise ContainerError(f"its zip member {info.filename!r} inflates past its declared size: a zip bomb, "
                                 "not a model")
        parts[info.filename.lower()] = data
    return parts


def split_text_package(text: str) -> tuple[str, dict[str, bytes]]:
    """A text-package ``.mdl``: (the classic stub before the package, its XML parts by lower-case name)."""
    begin = re.search(r"^__MWOPC_PACKAGE_BEGIN__.*$", text, re.MULTILINE)
    if begin is None:
        return text, {}
    stub, body = text[:begin.start()], text[begin.end():]
    parts: dict[str, bytes] = {}
    pieces = re.split(r"^__MWOPC_PART_BEGIN__[ \t]*(.*)$", body, flags=re.MULTILINE)
    if len(pieces) // 2 > MAX_MEMBERS:
        raise ContainerError(f"its package has more than {MAX_MEMBERS:,} parts")
    for header, content in zip(pieces[1::2], pieces[2::2]):
        fields = header.split()
        if not fields:
            raise ContainerError("a part of its package has no name (`__MWOPC_PART_BEGIN__` alone on a line)")
        name = fields[0].lstrip("/")
        _check_name(name)
        end = content.find("\n__MWOPC_PACKAGE_END__")
        content = content if end < 0 else content[:end]
        if "BASE64" in fields[1:] or not _wanted(name):
            continue
        parts[name.lower()] = content.strip("\r\n").encode("utf-8")
    return stub, parts


class _Budget(ElementTree.TreeBuilder):
    """Counts elements and their depth as each opens (and the nesting of <System>s, for its own message)."""

    def __init__(self, max_systems: int):
        super().__init__()
        self.depth = 0
        self.count = 0
        self.systems = 0
        self.max_systems = max_systems

    def start(self, tag, attrs):
        self.depth += 1
        self.count += 1
        if tag == "System":
            self.systems += 1
            if self.systems > self.max_systems:
                raise ContainerError(f"its subsystems nest more than {self.max_systems} deep", depth=True)
        if self.depth > MAX_XML_DEPTH:
            raise ContainerError(f"its XML nests more than {MAX_XML_DEPTH} elements deep")
        if self.count > MAX_NODES:
            raise ContainerError(f"its XML has more than {MAX_NODES:,} elements")
        return super().start(tag, attrs)

    def end(self, tag):
        self.depth -= 1
        if tag == "System":
            self.systems -= 1
        return super().end(tag)


def parse_xml(data: bytes, part: str, max_systems: int) -> Node:
    """One XML part as a :class:`~odelab.formats.simulink.tree.Node` (DTDs, entities and external references
    refused; depth and count bounded)."""
    from defusedxml import DefusedXmlException
    from defusedxml.ElementTree import DefusedXMLParser

    if re.search(rb"<!DOCTYPE|<!ENTITY", data[:1_000_000], re.IGNORECASE):
        raise ContainerError(f"its part {part} declares a DTD or entities (<!DOCTYPE>/<!ENTITY>), which no Simulink "
                             "model has; refused before anything was expanded or fetched")
    builder = _Budget(max_systems)
    parser = DefusedXMLParser(target=builder, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    try:
        parser.feed(data)
        root = parser.close()
    except DefusedXmlException as exc:
        raise ContainerError(f"its part {part} uses {type(exc).__name__.replace('Forbidden', '').lower() or 'a DTD'} "
                             "declarations, which no Simulink model has; refused before anything was expanded or "
                             "fetched") from None
    except ElementTree.ParseError as exc:
        raise ContainerError(f"its part {part} is not well-formed XML ({exc})") from None
    try:
        return from_xml(root)
    except TreeError as exc:
        raise ContainerError(f"its part {part}: {exc}") from None
