"""What a mesh file's header promises against what the file holds: cut, short and padded files.

:func:`symtorch.io.read_mesh` runs these checks before (PLY, STL) or while (OFF, OBJ) it parses, so
that a file cut in transfer, or whose header counts disagree with its data, is an error naming what
is missing instead of a mesh with faces lost or pointing at the wrong vertices. Each check raises a
one-line ``ValueError`` (without the path, which the caller adds).

- text formats (OFF, OBJ, ASCII PLY): a last data line not ended by a newline is a cut line (its
  last number may be a prefix: vertex ``300`` of a cut ``3001``); all files of the shared benchmarks
  end with one. OFF and ASCII PLY counts must match the data lines exactly, neither fewer nor more.
- binary PLY: the bytes the header's elements need (list properties walked record by record, or
  vectorised when every list has the length of the first) must be what the file holds.
- STL: a binary file holds ``84 + 50 n`` bytes for the ``n`` triangles of its header; an ASCII file
  closes every facet and ends with ``endsolid``.
"""
from __future__ import annotations

import re
import struct
from typing import NamedTuple

import numpy as np

__all__ = ["PlyHeader", "ply_header", "check_ply", "check_stl", "cut_last_line"]

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_SLOW_WALK = 5_000_000  # list records walked one by one at most (mixed polygon sizes)


def _plural(name: str, n: int) -> str:
    words = {"vertex": "vertices", "face": "faces", "edge": "edges"}
    return name if n == 1 else words.get(name, name + "s")


def cut_last_line(text: str, comment: str = "#") -> str | None:
    """The last line of ``text`` when it holds data but no newline ends it (a cut file), else None."""
    if not text or text.endswith(("\n", "\r")):
        return None
    last = text.rsplit("\n", 1)[-1]
    data = last.split(comment, 1)[0].strip() if comment else last.strip()
    return data or None


def cut_message(line: str) -> str:
    return (f"the last line {line[:40]!r} has no newline at its end: the file looks cut (if it is "
            "complete, end it with a newline)")


class PlyHeader(NamedTuple):
    """A parsed PLY header: ``fmt`` (``ascii``, ``binary_little_endian``, ``binary_big_endian``),
    ``elements`` ``[(name, count, [(kind, name, dtype, count_dtype)])]`` (``kind`` ``"scalar"`` or
    ``"list"``) and ``offset``, the first byte after ``end_header``."""

    fmt: str
    elements: list
    offset: int


def ply_header(data: bytes) -> PlyHeader | None:
    """Parse the header of PLY bytes; None when they do not start with the ``ply`` magic line.

    Raises:
        ValueError: a header cut before ``end_header``, or a malformed format, element or property line.
    """
    if not re.match(rb"ply[ \t]*\r?\n", data[:8]):
        return None
    m = re.search(rb"\bend_header[ \t]*(\r\n|\n|\r|$)", data)
    if m is None:
        raise ValueError(f"PLY header is cut: no 'end_header' line in its {len(data)} bytes")
    fmt, elements = None, []
    for raw in data[:m.start()].decode("latin-1").splitlines()[1:]:
        tok = raw.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format":
            if len(tok) < 2 or tok[1] not in _FORMATS:
                raise ValueError(f"bad PLY format line {raw.strip()[:40]!r}")
            fmt = tok[1]
        elif tok[0] == "element":
            if len(tok) != 3 or not tok[2].isdigit():
                raise ValueError(f"bad PLY element line {raw.strip()[:40]!r}")
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            if not elements:
                raise ValueError(f"PLY property before any element: {raw.strip()[:40]!r}")
            props = elements[-1][2]
            if len(tok) == 5 and tok[1] == "list" and tok[2] in _PLY_TYPES and tok[3] in _PLY_TYPES:
                props.append(("list", tok[4], _PLY_TYPES[tok[3]], _PLY_TYPES[tok[2]]))
            elif len(tok) == 3 and tok[1] in _PLY_TYPES:
                props.append(("scalar", tok[2], _PLY_TYPES[tok[1]], None))
            else:
                raise ValueError(f"bad PLY property line {raw.strip()[:40]!r}")
        else:
            raise ValueError(f"unknown PLY header line {raw.strip()[:40]!r}")
    if fmt is None:
        raise ValueError("PLY header has no 'format' line")
    return PlyHeader(fmt, elements, m.end())


def check_ply(data: bytes) -> PlyHeader | None:
    """Check that a PLY file holds exactly the elements its header promises.

    Returns:
        the header, or None for bytes that are not PLY (left to the reader to refuse).

    Raises:
        ValueError: header cut or malformed; fewer records than promised (``header promises 2000
            faces, file holds 1412``); data after the promised records; a cut last line.
    """
    header = ply_header(data)
    if header is None:
        return None
    if header.fmt == "ascii":
        _check_ply_ascii(data[header.offset:].decode("latin-1"), header.elements)
    else:
        _check_ply_binary(data, header.offset, header.elements, _FORMATS[header.fmt])
    return header


def _short(name: str, promised: int, held: int, missing: str = "") -> ValueError:
    return ValueError(f"truncated: header promises {promised} {_plural(name, promised)}, file holds "
                      f"{held}{missing}")


def _check_ply_ascii(body: str, elements: list) -> None:
    lines = [s for s in body.splitlines() if s.strip()]
    i = 0
    for name, count, props in elements:
        held = min(count, len(lines) - i)
        if held < count:
            raise _short(name, count, held)
        scalars = sum(kind == "scalar" for kind, *_ in props)
        lists = [j for j, (kind, *_) in enumerate(props) if kind == "list"]
        for j in range(i, i + count):
            tok = lines[j].split()
            if lists:
                want, pos = 0, 0
                try:
                    for kind, *_ in props:
                        if kind == "list":
                            n = int(float(tok[pos]))
                            want, pos = want + 1 + n, pos + 1 + n
                        else:
                            want, pos = want + 1, pos + 1
                except (IndexError, ValueError):
                    want = -1
            else:
                want = scalars
            if len(tok) != want:
                raise ValueError(f"{name} {j - i} has {len(tok)} numbers where its properties "
                                 f"need {'another count' if want < 0 else want}: {lines[j][:40]!r}")
        i += count
    if i < len(lines):
        last = elements[-1][0] if elements else "element"
        raise ValueError(f"{len(lines) - i} data lines after the {sum(c for _, c, _ in elements)} "
                         f"records the header promises (it announces fewer than the file holds; "
                         f"the last element is {last!r})")
    line = cut_last_line(body, comment="")
    if line is not None:
        raise ValueError(cut_message(line))


def _check_ply_binary(data: bytes, pos: int, elements: list, endian: str) -> None:
    for name, count, props in elements:
        end, held = _binary_records(data, pos, count, props, endian)
        if end is None:
            raise _short(name, count, held)
        pos = end
    if pos < len(data) and data[pos:].strip(b" \t\r\n\x00"):
        raise ValueError(f"{len(data) - pos} bytes after the records the header promises (it "
                         "announces fewer than the file holds)")


def _binary_records(data: bytes, pos: int, count: int, props: list,
                    endian: str) -> tuple[int | None, int]:
    """(end offset, count) of ``count`` records from ``pos``, or (None, complete records held)."""
    size = len(data)
    lists = [j for j, (kind, *_) in enumerate(props) if kind == "list"]
    width = [np.dtype(t).itemsize for _, _, t, _ in props]
    if not lists:
        stride = sum(width)
        if stride == 0 or pos + count * stride <= size:
            return pos + count * stride, count
        return None, max(0, (size - pos) // stride)
    done = 0
    if len(lists) == 1:  # one list: if every list has the first one's length, records are equal
        j = lists[0]
        pre = sum(width[:j])
        ctype = np.dtype(endian + props[j][3])
        post = sum(width[j + 1:])
        if pos + pre + ctype.itemsize > size:
            return (pos, 0) if count == 0 else (None, 0)
        n0 = int(np.frombuffer(data, ctype, 1, pos + pre)[0])
        stride = pre + ctype.itemsize + n0 * width[j] + post
        fit = min(count, (size - pos) // stride)
        counts = np.ndarray((fit,), ctype, data, pos + pre, (stride,)) if fit else np.zeros(0)
        if (counts == n0).all():
            if fit == count:
                return pos + count * stride, count
            done, pos = fit, pos + fit * stride  # the rest, if any fits, record by record
    if count - done > _SLOW_WALK:
        raise ValueError(f"too many records of mixed list lengths to check ({count})")
    types = {t for _, _, t, _ in props} | {c for _, _, _, c in props if c}
    fmt = {t: struct.Struct(endian + np.dtype(t).char) for t in types}
    for i in range(done, count):
        for (kind, _, t, c), w in zip(props, width):
            if kind == "list":
                cs = fmt[c].size
                if pos + cs > size:
                    return None, i
                n = fmt[c].unpack_from(data, pos)[0]
                pos += cs + n * w
            else:
                pos += w
        if pos > size:
            return None, i
    return pos, count


def check_stl(data: bytes) -> None:
    """Check that an STL file holds the triangles its header promises (binary) or closes them (ASCII).

    Raises:
        ValueError: a binary file shorter or longer than ``84 + 50 n`` bytes, an ASCII file cut
            before ``endsolid``.
    """
    size = len(data)
    if size >= 84 and 84 + 50 * struct.unpack_from("<I", data, 80)[0] == size:
        return  # binary, complete
    head = data[:1024]
    if head.lstrip()[:5].lower() == b"solid" and b"\x00" not in head:
        _check_stl_ascii(data.decode("latin-1"))
        return
    if size < 84:
        raise ValueError(f"binary STL cut inside its 84-byte header ({size} bytes)")
    n = struct.unpack_from("<I", data, 80)[0]
    held = (size - 84) // 50
    if held < n:
        raise _short("triangle", n, held, f" ({84 + 50 * n - size} bytes missing)")
    raise ValueError(f"binary STL header promises {n} triangles but {size - 84 - 50 * n} bytes "
                     "follow them")


def _check_stl_ascii(text: str) -> None:
    begun = len(re.findall(r"\bfacet\b", text))
    ended = len(re.findall(r"\bendfacet\b", text))
    corners = len(re.findall(r"\bvertex\b", text))
    last = [s for s in text.splitlines() if s.strip()][-1].split()
    if begun != ended or corners != 3 * begun or last[0].lower() != "endsolid":
        raise ValueError(f"ASCII STL is cut: {begun} facets begun, {ended} ended, {corners} vertex "
                         f"lines, {'no' if last[0].lower() != 'endsolid' else 'an'} 'endsolid' line "
                         "at the end")
