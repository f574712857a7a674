"""Tolerant BVH text parsing: the hierarchy and the MOTION block, with one-line errors.

What is accepted beyond the strict format, since common exporters write it:
- a UTF-8 (or UTF-16) byte-order mark, Latin-1 joint names, a trailing DOS end-of-file mark;
- LF, CRLF or lone-CR line endings; tabs, repeated whitespace and blank lines anywhere;
- braces on the same line as a keyword (``ROOT Hips {``, ``} }``, ``End Site { OFFSET 0 1 0 }``);
- keywords and channel names in any letter case (``End Site``, ``END SITE``, ``xrotation``);
  ``Frames:``/``Frame Time:`` with any spacing (``Frame  Time :0.0083``), in either order;
- joint names with spaces or colons (``mixamorig:Hips``): the rest of the ROOT/JOINT line is the name;
- numbers in any form ``float()`` reads (``1e-05``, ``+3``); ``inf``/``nan`` are rejected;
- motion values wrapped differently from one frame per line: the values are counted, not the lines, when the
  wrapping is consistent (every line but the last of the same length, or every frame split the same way);
- more frames of data than ``Frames:`` declares: the declared count is used and the extra frames are ignored
  (they must still be finite numbers). Fewer frames than declared is an error.
"""
from __future__ import annotations

import re
from typing import Optional

import numpy as np

from inbetween_jax.data.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton

KNOWN_CHANNELS = POSITION_CHANNELS + ROTATION_CHANNELS
_CHANNEL_BY_LOWER = {c.lower(): c for c in KNOWN_CHANNELS}
_TOKEN = re.compile(r"[{}]|[^\s{}]+")
_STATEMENTS = {"root", "joint", "end", "endsite", "offset", "channels", "motion", "hierarchy"}
_FRAMES = re.compile(r"frames\s*:?\s*(.*)", re.IGNORECASE)
_FRAME_TIME = re.compile(r"frame\s*time\s*:?\s*(.*)", re.IGNORECASE)


class BVHError(ValueError):
    """A BVH file could not be read; the message is ``"<file>:<line>: <problem>"``."""

    def __init__(self, path, line: Optional[int], problem: str):
        self.path, self.line, self.problem = str(path), line, problem
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {problem}")


def _show(text: str, limit: int = 60) -> str:
    """repr of ``text``, shortened so that an error message stays one readable line."""
    return repr(text if len(text) <= limit else text[:limit] + "...")


def read_lines(path: str) -> list:
    """The file's text lines (any line ending, byte-order mark removed)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise BVHError(path, None, "file not found") from None
    except IsADirectoryError:
        raise BVHError(path, None, "is a directory, not a BVH file") from None
    except OSError as e:
        raise BVHError(path, None, f"cannot read the file ({e.strerror or e})") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        encoding = "utf-16"
    elif b"\x00" in raw:
        raise BVHError(path, None, "not a text file (binary data: NUL bytes)")
    else:
        encoding = "utf-8-sig"
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as e:
        body = raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw
        if body.lstrip()[:9].upper() != b"HIERARCHY":
            raise BVHError(path, None, f"not a text file ({e.reason} at byte {e.start})") from None
        text = body.decode("latin-1")  # a BVH file with joint names in a legacy 8-bit encoding
    text = text.lstrip("\ufeff").rstrip("\x1a")  # byte-order mark; DOS end-of-file mark
    if not text.strip():
        raise BVHError(path, None, "empty file (missing HIERARCHY header)")
    return text.splitlines()


def parse_hierarchy(path: str, lines: list):
    """Parse HIERARCHY up to MOTION. Returns (Skeleton, index of the line after MOTION)."""
    names, parents, offsets, channels, end_sites, decl = [], [], [], [], [], []
    stack = []  # joint index or "end"
    pending = None  # (joint index or "end", description) waiting for "{"
    i = next((k for k, ln in enumerate(lines) if ln.strip()), len(lines))
    first = lines[i].split() if i < len(lines) else []
    if not first or first[0].upper() != "HIERARCHY":
        raise BVHError(path, i + 1 if i < len(lines) else None, "missing HIERARCHY header")
    rest = ((k + 1, _TOKEN.findall(lines[k])[1 if k == i else 0:]) for k in range(i, len(lines)))
    lineno = len(lines)
    for lineno, toks in rest:
        k = 0
        while k < len(toks):
            tok, key = toks[k], toks[k].lower()
            if pending is not None and tok != "{":
                raise BVHError(path, lineno, f"expected '{{' after {pending[1]}, got {_show(tok)}")
            if tok == "{":
                if pending is None:
                    raise BVHError(path, lineno, "unexpected '{'")
                stack.append(pending[0])
                pending = None
                k += 1
                continue
            if tok == "}":
                if not stack:
                    raise BVHError(path, lineno, "unbalanced '}'")
                stack.pop()
                k += 1
                continue
            if key in ("root", "joint"):
                stop = next((n for n in range(k + 1, len(toks)) if toks[n] in "{}"), len(toks))
                name, kw = " ".join(toks[k + 1:stop]), key.upper()
                if not name:
                    raise BVHError(path, lineno, f"{kw} without a name")
                if key == "root" and names:
                    raise BVHError(path, lineno, "more than one ROOT is not supported")
                if key == "joint" and (not stack or stack[-1] == "end"):
                    raise BVHError(path, lineno, "JOINT outside a joint block")
                if name in names:
                    raise BVHError(path, lineno, f"joint name {name!r} appears more than once")
                names.append(name)
                decl.append(lineno)
                parents.append(stack[-1] if stack else -1)
                offsets.append(None)
                channels.append(())
                pending = (len(names) - 1, f"{kw} {name!r}")
                k = stop
                continue
            if key == "end" or key == "endsite":
                if key == "end" and (k + 1 >= len(toks) or toks[k + 1].lower() != "site"):
                    raise BVHError(path, lineno, f"unexpected {_show(tok)} in HIERARCHY (expected 'End Site')")
                if not stack or stack[-1] == "end":
                    raise BVHError(path, lineno, "End Site outside a joint block")
                end_sites.append([stack[-1], None])
                pending = ("end", "End Site")
                # an exporter may name the end site: skip any words up to the brace
                k = next((n for n in range(k + 1, len(toks)) if toks[n] in "{}"), len(toks))
                continue
            if key == "motion":
                if stack:
                    raise BVHError(path, lineno, "MOTION before every '{' was closed")
                if k + 1 < len(toks):
                    raise BVHError(path, lineno, f"unexpected {_show(' '.join(toks[k + 1:]))} after MOTION")
                break
            if key not in ("offset", "channels"):
                raise BVHError(path, lineno, f"unexpected {_show(tok)} in HIERARCHY")
            stop = next((n for n in range(k + 1, len(toks))
                         if toks[n] in "{}" or toks[n].lower() in _STATEMENTS), len(toks))
            args = toks[k + 1:stop]
            k = stop
            if key == "offset":
                if not stack:
                    raise BVHError(path, lineno, "OFFSET outside a joint block")
                try:
                    vals = np.array([float(w) for w in args], np.float64)
                except ValueError:
                    raise BVHError(path, lineno, f"non-numeric OFFSET {_show(' '.join(args))}") from None
                if vals.shape != (3,) or not np.all(np.isfinite(vals)):
                    raise BVHError(path, lineno, f"OFFSET needs 3 finite numbers, got {_show(' '.join(args))}")
                if stack[-1] == "end":
                    end_sites[-1][1] = vals
                else:
                    offsets[stack[-1]] = vals
                continue
            if not stack or stack[-1] == "end":
                raise BVHError(path, lineno, "CHANNELS outside a joint block")
            try:
                n = int(args[0])
            except (IndexError, ValueError):
                raise BVHError(path, lineno, "CHANNELS needs a count") from None
            if len(args) - 1 != n:
                raise BVHError(path, lineno, f"CHANNELS says {n} but lists {len(args) - 1} names")
            chans = []
            for c in args[1:]:
                if c.lower() not in _CHANNEL_BY_LOWER:
                    raise BVHError(path, lineno, f"unknown channel name {_show(c)} (expected one of {KNOWN_CHANNELS})")
                chans.append(_CHANNEL_BY_LOWER[c.lower()])
            rot = [c for c in chans if c in ROTATION_CHANNELS]
            if len(rot) not in (0, 3) or len(set(rot)) != len(rot) or len(set(chans)) != len(chans):
                raise BVHError(path, lineno, f"channels must be distinct with 0 or 3 rotation axes, got {chans}")
            channels[stack[-1]] = tuple(chans)
        else:
            continue
        break  # MOTION
    else:
        raise BVHError(path, len(lines), "file ends before the MOTION section")
    if not names:
        raise BVHError(path, None, "no ROOT joint")
    for j, o in enumerate(offsets):
        if o is None:
            raise BVHError(path, decl[j], f"joint {names[j]!r} has no OFFSET")
    skel = Skeleton(tuple(names), tuple(parents), np.stack(offsets), tuple(channels),
                    tuple((p, o if o is not None else np.zeros(3)) for p, o in end_sites))
    return skel, lineno


def _parse_header(path, lines, i):
    """``Frames:`` and ``Frame Time:`` (either order). Returns (frames, frame_time, index after them)."""
    found = {}
    while len(found) < 2:
        while i < len(lines) and not lines[i].strip():
            i += 1
        missing = "Frames:" if "Frames:" not in found else "Frame Time:"
        if i >= len(lines):
            raise BVHError(path, len(lines), f"file ends before the '{missing}' line")
        text = lines[i].strip()
        for key, pattern in (("Frame Time:", _FRAME_TIME), ("Frames:", _FRAMES)):
            m = pattern.fullmatch(text)
            if m and key not in found:
                try:
                    found[key] = (float(m.group(1)), i + 1)
                except ValueError:
                    raise BVHError(path, i + 1, f"bad value in {_show(text)}") from None
                break
        else:
            raise BVHError(path, i + 1, f"expected '{missing}' line, got {_show(text)}")
        i += 1
    (frames, frames_line), (frame_time, time_line) = found["Frames:"], found["Frame Time:"]
    if not np.isfinite(frames) or frames != int(frames) or frames < 1:
        got = _show(lines[frames_line - 1].strip())
        raise BVHError(path, frames_line, f"Frames must be a positive integer, got {got}")
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise BVHError(path, time_line, f"Frame Time must be positive, got {frame_time}")
    return int(frames), frame_time, i


def _layout_ok(counts: list, nchan: int) -> bool:
    """Whether per-line value counts split into frames of ``nchan`` values in a consistent way."""
    if all(c == nchan for c in counts):
        return True
    if sum(counts) % nchan:
        return False
    head = counts[:-1]
    if all(c == counts[0] for c in head) and counts[0] != nchan and 0 < counts[-1] <= counts[0]:
        return True  # one stream of values wrapped at a fixed width
    cum = np.cumsum(counts)
    per = int(np.searchsorted(cum, nchan)) + 1  # lines of the first frame
    if per > len(counts) or cum[per - 1] != nchan or len(counts) % per:
        return False
    return counts == counts[:per] * (len(counts) // per)  # every frame split the same way


def parse_motion(path: str, lines: list, start: int, nchan: int, notes: Optional[list] = None):
    """Parse the MOTION block after line index ``start``. Returns (values (T, C) float64, frame_time).
    Frames beyond the ``Frames:`` count are dropped; ``notes`` (a list) gets a line saying so."""
    frames, frame_time, i = _parse_header(path, lines, start)
    if nchan == 0:
        raise BVHError(path, start, "the hierarchy declares no channels")
    data = [(k + 1, ln.split()) for k, ln in enumerate(lines[i:], start=i) if ln.strip()]
    counts = [len(w) for _, w in data]
    last_line = data[-1][0] if data else i
    if data and not _layout_ok(counts, nchan):
        if counts[0] == nchan:
            lineno, c = next((n, len(w)) for n, w in data if len(w) != nchan)
            if lineno == last_line and c < nchan:
                raise BVHError(path, lineno, f"truncated MOTION block: the last frame has {c} values, "
                                             f"the hierarchy declares {nchan} channels")
            raise BVHError(path, lineno, f"frame has {c} values, the hierarchy declares {nchan} channels")
        lineno = next((n for (n, w), c in zip(data[:-1], counts) if c != counts[0]), last_line)
        raise BVHError(path, lineno, f"{sum(counts)} motion values on {len(counts)} lines do not split "
                                     f"consistently into frames of {nchan} channels")
    total = sum(counts)
    if total < frames * nchan:
        raise BVHError(path, last_line, f"truncated MOTION block: header says {frames} frames, "
                                        f"found {total // nchan}")
    words = [w for _, ws in data for w in ws]
    try:
        values = np.array(words, dtype=np.float64)
    except ValueError:
        values = None
    bad = None
    if values is None:
        bad = next((n for n, w in enumerate(words) if not _is_float(w)), None)
        problem = "non-numeric"
        if bad is None:  # numpy refused what float() reads
            values = np.array([float(w) for w in words], np.float64)
    if values is not None and not np.all(np.isfinite(values)):
        bad = int(np.argmax(~np.isfinite(values)))
        problem = "non-finite"
    if bad is not None:
        row = int(np.searchsorted(np.cumsum(counts), bad, side="right"))
        col = bad - (int(np.sum(counts[:row])) if row else 0)
        raise BVHError(path, data[row][0], f"{problem} value {_show(words[bad])} in column {col + 1}")
    extra = total // nchan - frames
    if extra and notes is not None:
        notes.append(f"{path}: {extra} frame{'s' if extra != 1 else ''} of motion data beyond its "
                     f"'Frames: {frames}' line ignored")
    return values.reshape(-1, nchan)[:frames], frame_time


def _is_float(word: str) -> bool:
    try:
        float(word)
        return True
    except ValueError:
        return False
