"""BVH variants that exporters write read the same as the original; files that are not BVH get one clear line.

Each variant is a text rewrite of a real shipped file (an embedded CMU clip, and a CMU salsa file whose root
Euler order differs from every other joint's) and must parse to the original's quaternions and positions.
"""
import os
import re

import numpy as np
import pytest

from inbetween_jax.data import BVHError, read_bvh
from inbetween_jax.data.datasets import EMBEDDED_DIR

from conftest import LAFAN1_DIR, SHARED_DATA

FRAMES = 40  # frames kept from each source file: enough to exercise every rewrite, fast to parse


def _cmu_pair_file():
    for root in (SHARED_DATA, os.path.dirname(os.path.abspath(LAFAN1_DIR))):
        path = os.path.join(root, "cmu_pairs", "60_01_scaled.bvh")
        if os.path.exists(path):
            return path
    return None


SOURCES = {"embedded": os.path.join(EMBEDDED_DIR, "02_01.bvh"), "cmu_pairs": _cmu_pair_file()}


def _parts(text):
    """(hierarchy lines up to MOTION, 'Frames:' line, 'Frame Time:' line, data lines)."""
    lines = text.split("\n")
    m = next(k for k, ln in enumerate(lines) if ln.strip().upper() == "MOTION")
    return lines[:m + 1], lines[m + 1], lines[m + 2], [ln for ln in lines[m + 3:] if ln.strip()]


def _join(head, frames, ftime, data):
    return "\n".join(head + [frames, ftime] + data) + "\n"


@pytest.fixture(scope="module", params=sorted(SOURCES))
def source(request, tmp_path_factory):
    """(name, path of the first FRAMES frames of a real file as written, its Motion read directly)."""
    path = SOURCES[request.param]
    if path is None:
        pytest.skip("shared CMU salsa data (cmu_pairs) not available")
    with open(path, newline="") as fh:
        head, _, ftime, data = _parts(fh.read())
    out = tmp_path_factory.mktemp("src") / f"{request.param}.bvh"
    out.write_text(_join(head, f"Frames: {FRAMES}", ftime, data[:FRAMES]))
    ref = read_bvh(path, 0, FRAMES)
    return request.param, out.read_text(), ref


def _on_data(fn):
    """Rewrite every motion value token with ``fn``."""
    def rewrite(text):
        head, frames, ftime, data = _parts(text)
        return _join(head, frames, ftime, [" ".join(fn(w) for w in ln.split()) for ln in data])
    return rewrite


def _rewrap(widths=None, per_line=None):
    """Motion values re-wrapped: each frame split at ``widths``, or the value stream ``per_line`` per line."""
    def rewrite(text):
        head, frames, ftime, data = _parts(text)
        rows = [ln.split() for ln in data]
        if widths is not None:
            cuts = [0, *widths, None]
            out = [" ".join(r[a:b]) for r in rows for a, b in zip(cuts[:-1], cuts[1:])]
        else:
            flat = [w for r in rows for w in r]
            n = per_line(len(rows[0])) if callable(per_line) else per_line
            out = [" ".join(flat[k:k + n]) for k in range(0, len(flat), n)]
        return _join(head, frames, ftime, out)
    return rewrite


_KEYWORD = re.compile(r"^(\s*)(HIERARCHY|ROOT|JOINT|End Site|OFFSET|CHANNELS|MOTION|Frames:|Frame Time:)(?=\s|$)",
                      re.MULTILINE)


def _recase(fn):
    return lambda text: _KEYWORD.sub(lambda m: m.group(1) + fn(m.group(2)), text)


def _rename(prefix):
    pattern = re.compile(r"^(\s*)(ROOT|JOINT) (\S+)", re.MULTILINE)
    return lambda text: pattern.sub(lambda m: f"{m.group(1)}{m.group(2)} {prefix}{m.group(3)}", text)


def _scientific(fmt):
    def rewrite(text):
        text = re.sub(r"(OFFSET)((?:\s+\S+){3})",
                      lambda m: m.group(1) + " " + " ".join(fmt % float(w) for w in m.group(2).split()), text)
        return _on_data(lambda w: fmt % float(w))(text)
    return rewrite


def _root_rotation_only(text):
    """Drop the root's position channels and their columns."""
    head, frames, ftime, data = _parts(text)
    k = next(n for n, ln in enumerate(head) if "CHANNELS" in ln)
    chans = head[k].split()[2:]
    keep = [n for n, c in enumerate(chans) if "rotation" in c]
    head[k] = re.sub(r"CHANNELS .*", f"CHANNELS {len(keep)} " + " ".join(chans[n] for n in keep), head[k])
    rows = [ln.split() for ln in data]
    drop = {n for n in range(len(chans)) if n not in keep}
    return _join(head, frames, ftime, [" ".join(w for n, w in enumerate(r) if n not in drop) for r in rows])


def _child_six_channels(text):
    """Joint 1 gets position channels interleaved with its rotations, valued at its OFFSET."""
    head, frames, ftime, data = _parts(text)
    idx = [n for n, ln in enumerate(head) if "CHANNELS" in ln]
    col = int(head[idx[0]].split()[1])  # joint 1's first column
    off = next(ln for ln in head[idx[0]:idx[1]][::-1] if "OFFSET" in ln).split()[1:]
    rot = head[idx[1]].split()[2:]
    chans = [rot[0], "Yposition", rot[1], "Xposition", "Zposition", rot[2]]
    head[idx[1]] = re.sub(r"CHANNELS .*", "CHANNELS 6 " + " ".join(chans), head[idx[1]])
    out = []
    for ln in data:
        r = ln.split()
        r = r[:col] + [r[col], off[1], r[col + 1], off[0], off[2], r[col + 2]] + r[col + 3:]
        out.append(" ".join(r))
    return _join(head, frames, ftime, out)


def _root_position_order(text):
    """Root position channels listed Z X Y with the columns permuted to match."""
    head, frames, ftime, data = _parts(text)
    k = next(n for n, ln in enumerate(head) if "CHANNELS" in ln)
    head[k] = head[k].replace("Xposition Yposition Zposition", "Zposition Xposition Yposition")
    rows = [ln.split() for ln in data]
    return _join(head, frames, ftime, [" ".join([r[2], r[0], r[1]] + r[3:]) for r in rows])


def _declare(n):
    def rewrite(text):
        head, _, ftime, data = _parts(text)
        return _join(head, f"Frames: {n}", ftime, data)
    return rewrite


def _chain(*fns):
    def rewrite(text):
        for fn in fns:
            text = fn(text) if isinstance(text, str) else text
        return text
    return rewrite


_SUB = lambda pattern, repl: (lambda text: re.sub(pattern, repl, text, flags=re.MULTILINE))  # noqa: E731

# name -> (rewrite of the text (str or bytes), change to the expected result or None)
VARIANTS = {
    "keywords_lower": (_recase(str.lower), None),
    "keywords_upper": (_recase(str.upper), None),
    "keywords_title": (_recase(str.title), None),
    "keywords_swapcase": (_recase(str.swapcase), None),
    "end_site_upper": (lambda t: t.replace("End Site", "END SITE"), None),
    "end_site_lower_site": (lambda t: t.replace("End Site", "End site"), None),
    "channel_names_upper": (_SUB(r"\b[XYZ](rotation|position)\b", lambda m: m.group(0).upper()), None),
    "channel_names_lower": (_SUB(r"\b[XYZ](rotation|position)\b", lambda m: m.group(0).lower()), None),
    "utf8_bom": (lambda t: b"\xef\xbb\xbf" + t.encode(), None),
    "utf16_bom": (lambda t: t.encode("utf-16"), None),
    "crlf": (lambda t: t.replace("\n", "\r\n"), None),
    "lone_cr": (lambda t: t.replace("\n", "\r"), None),
    "mixed_line_endings": (lambda t: "".join(ln + ("\r\n", "\n", "\r")[k % 3]
                                             for k, ln in enumerate(t.split("\n"))), None),
    "no_final_newline": (lambda t: t.rstrip("\n"), None),
    "tabs_to_spaces": (lambda t: t.replace("\t", "    "), None),
    "no_indentation": (_SUB(r"^[ \t]+", ""), None),
    "repeated_whitespace": (_SUB(r"[ \t]+", " \t  "), None),
    "tabs_between_tokens": (lambda t: t.replace(" ", "\t"), None),
    "blank_lines_everywhere": (lambda t: "\n \n" + "".join(ln + ("\n\n", "\n\t \n", "\n")[k % 3]
                                                           for k, ln in enumerate(t.split("\n"))), None),
    "trailing_whitespace": (lambda t: "".join(ln + " \t \n" for ln in t.split("\n")) + "\n\n \t\n\n", None),
    "frame_time_no_space": (_SUB(r"^Frame Time:\s*", "Frame Time:"), None),
    "frame_time_extra_spaces": (_SUB(r"^Frame Time:\s*", "Frame   Time :   "), None),
    "frames_no_space": (_SUB(r"^Frames:\s*", "Frames:"), None),
    "frames_extra_spaces": (_SUB(r"^Frames:\s*", "Frames  :\t "), None),
    "header_order_swapped": (_SUB(r"^(Frames:.*)\n(Frame Time:.*)$", r"\2\n\1"), None),
    "scientific_lower": (_scientific("%.17e"), None),
    "scientific_upper": (_scientific("%.17E"), None),
    "explicit_plus_sign": (_on_data(lambda w: w if w.startswith("-") else "+" + w), None),
    "frames_split_in_two": (_rewrap(widths=[7]), None),
    "frames_split_unevenly": (_rewrap(widths=[10, 60]), None),
    "stream_10_per_line": (_rewrap(per_line=10), None),
    "all_values_one_line": (_rewrap(per_line=10 ** 9), None),
    "two_frames_per_line": (_rewrap(per_line=lambda c: 2 * c), None),
    "more_frames_than_declared": (_declare(FRAMES - 5), "first_35"),
    "brace_on_keyword_line": (_SUB(r"\n[ \t]*\{", " {"), None),
    "closing_braces_joined": (_SUB(r"\}[ \t]*\n[ \t]*(?=\})", "} "), None),
    "end_site_one_line": (_SUB(r"End Site\s*\{\s*(OFFSET[^\n]*?)\s*\n\s*\}", r"End Site { \1 }"), None),
    "names_with_colon": (_rename("mixamorig:"), "names:mixamorig:"),
    "names_in_latin1": (lambda t: _rename("Kn\xe4")(t).encode("latin-1"), "names:Kn\xe4"),
    "dos_end_of_file_mark": (lambda t: t + "\x1a", None),
    "names_with_space": (_rename("Character 1:"), "names:Character 1:"),
    "root_rotation_only": (_root_rotation_only, "root_rotation_only"),
    "child_six_channels": (_child_six_channels, "child_six_channels"),
    "root_position_order": (_root_position_order, "root_position_order"),
    "everything_at_once": (_chain(_scientific("%.17e"), _rewrap(per_line=17), _recase(str.lower),
                                  _SUB(r"[ \t]+", "\t "), lambda t: b"\xef\xbb\xbf" + t.replace("\n", "\r\n").encode()),
                           None),
}


def _expected(ref, change):
    """(names, channels, quats (T, J, 4), positions (T, J, 3)) the variant must read as."""
    names, chans = list(ref.skeleton.names), list(ref.skeleton.channels)
    quats, pos = ref.local_quats, ref.local_pos.copy()
    if change == "first_35":
        quats, pos = quats[:FRAMES - 5], pos[:FRAMES - 5]
    elif change and change.startswith("names:"):
        names = [change[len("names:"):] + n for n in names]
    elif change == "root_rotation_only":
        chans[0] = tuple(c for c in chans[0] if "rotation" in c)
        pos[:, 0] = ref.skeleton.offsets[0]
    elif change == "child_six_channels":
        r = chans[1]
        chans[1] = (r[0], "Yposition", r[1], "Xposition", "Zposition", r[2])
    elif change == "root_position_order":
        chans[0] = ("Zposition", "Xposition", "Yposition") + chans[0][3:]
    return names, chans, quats, pos


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_variant_reads_like_the_original(source, variant, tmp_path):
    name, text, ref = source
    rewrite, change = VARIANTS[variant]
    body = rewrite(text)
    assert body != text
    path = tmp_path / f"{name}_{variant}.bvh"
    path.write_bytes(body if isinstance(body, bytes) else body.encode())
    m = read_bvh(path)
    names, chans, quats, pos = _expected(ref, change)
    assert list(m.skeleton.names) == names
    assert m.skeleton.parents == ref.skeleton.parents
    assert list(m.skeleton.channels) == chans
    np.testing.assert_allclose(m.skeleton.offsets, ref.skeleton.offsets, atol=1e-12)
    assert len(m.skeleton.end_sites) == len(ref.skeleton.end_sites)
    for (p1, o1), (p2, o2) in zip(m.skeleton.end_sites, ref.skeleton.end_sites):
        assert p1 == p2 and np.allclose(o1, o2, atol=1e-12)
    assert m.frame_time == pytest.approx(ref.frame_time, rel=1e-12)
    assert m.local_quats.shape == quats.shape
    np.testing.assert_allclose(m.local_quats, quats, atol=1e-12)
    np.testing.assert_allclose(m.local_pos, pos, atol=1e-12)


def test_sources_have_per_joint_euler_orders(source):
    """The sources exercise a root Euler order that differs from the other joints' (as CMU files have)."""
    _, _, ref = source
    orders = {ref.skeleton.rotation_order(j) for j in range(ref.skeleton.num_joints)} - {""}
    assert ref.skeleton.rotation_order(0) == "zyx" and "zxy" in orders
    assert len(ref.skeleton.end_sites) > 0 and ref.num_frames == FRAMES


def _replace_row(k, fn):
    """Rewrite data row ``k`` (a list of value strings) with ``fn``."""
    def rewrite(text):
        head, frames, ftime, data = _parts(text)
        rows = [ln.split() for ln in data]
        rows[k] = fn(rows[k])
        return _join(head, frames, ftime, [" ".join(r) for r in rows])
    return rewrite


def _set_value(k, col, value):
    return _replace_row(k, lambda r: r[:col] + [value] + r[col + 1:])


def _cut_at(marker):
    return lambda t: t[:t.index(marker)]


# name -> (rewrite of the text, words the one-line message must contain, expected line number or None)
BAD = {
    "empty": (lambda t: b"", "empty file", None),
    "only_whitespace": (lambda t: " \n\t\r\n\n", "empty file", None),
    "only_bom": (lambda t: b"\xef\xbb\xbf\n", "empty file", None),
    "binary_nul": (lambda t: b"Kaydara FBX Binary  \x00\x1a\x00\xe8\x1c\x00\x00", "not a text file (binary data", None),
    "binary_non_utf8": (lambda t: bytes(range(128, 256)) * 4, "not a text file", None),
    "other_text_format": (lambda t: '{"frames": [1, 2, 3]}\n', "missing HIERARCHY", 1),
    "truncated_hierarchy": (_cut_at("JOINT lFoot"), "file ends before the MOTION section", None),
    "truncated_mid_line": (lambda t: t[:t.index("OFFSET", 500) + 9], "OFFSET needs 3 finite numbers", None),
    "no_frames_line": (_cut_at("Frames:"), "file ends before the 'Frames:' line", None),
    "no_frame_time_line": (_SUB(r"^Frame Time:.*\n", ""), "expected 'Frame Time:' line", None),
    "zero_frames": (_declare(0), "Frames must be a positive integer", None),
    "negative_frames": (_declare(-3), "Frames must be a positive integer", None),
    "fractional_frames": (_declare(2.5), "Frames must be a positive integer", None),
    "zero_frame_time": (_SUB(r"^Frame Time:.*$", "Frame Time: 0"), "Frame Time must be positive", None),
    "negative_frame_time": (_SUB(r"^Frame Time:.*$", "Frame Time: -0.0333"), "Frame Time must be positive", None),
    "nan_frame_time": (_SUB(r"^Frame Time:.*$", "Frame Time: nan"), "Frame Time must be positive", None),
    "text_frame_time": (_SUB(r"^Frame Time:.*$", "Frame Time: fast"), "bad value", None),
    "fewer_frames_than_declared": (_declare(FRAMES + 1), "truncated MOTION block: header says 41 frames, found 40",
                                   None),
    "value_missing": (_replace_row(FRAMES - 1, lambda r: r[:-1]), "values", None),
    "value_extra": (_replace_row(3, lambda r: r + ["0.5"]), "frame has", None),
    "nan_value": (_set_value(5, 7, "nan"), "non-finite value 'nan' in column 8", None),
    "inf_value": (_set_value(6, 0, "-inf"), "non-finite value '-inf' in column 1", None),
    "msvc_nan": (_set_value(7, 4, "1.#IND"), "non-numeric value '1.#IND' in column 5", None),
    "comma_decimal": (_set_value(7, 4, "0,5"), "non-numeric value '0,5' in column 5", None),
    "nan_offset": (lambda t: re.sub(r"OFFSET \S+", "OFFSET nan", t, count=3), "OFFSET needs 3 finite numbers", None),
    "extra_close_brace": (lambda t: t.replace("MOTION", "}\nMOTION"), "unbalanced '}'", None),
    "missing_close_brace": (lambda t: t.replace("}\nMOTION", "MOTION"), "MOTION before every '{' was closed", None),
    "missing_open_brace": (lambda t: t.replace("JOINT abdomen\n\t{", "JOINT abdomen"), "expected '{' after JOINT",
                           None),
    "end_without_site": (lambda t: t.replace("End Site", "End", 1), "expected 'End Site'", None),
    "unknown_channel": (lambda t: t.replace("Zrotation", "Wrotation", 1), "unknown channel name 'Wrotation'", 5),
    "channel_count": (lambda t: t.replace("CHANNELS 3", "CHANNELS 4", 1), "CHANNELS says 4", 9),
    "second_root": (lambda t: t.replace("MOTION", "ROOT again\n{\n\tOFFSET 0 0 0\n}\nMOTION"), "more than one ROOT",
                    None),
    "garbage_in_hierarchy": (lambda t: t.replace("JOINT chest", "BONE chest"), "unexpected 'BONE'", 10),
}


@pytest.fixture(scope="module")
def embedded_text(tmp_path_factory):
    with open(SOURCES["embedded"]) as fh:
        head, _, ftime, data = _parts(fh.read())
    return _join(head, f"Frames: {FRAMES}", ftime, data[:FRAMES])


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_file_one_line_error(embedded_text, case, tmp_path):
    rewrite, words, line = BAD[case]
    body = rewrite(embedded_text)
    path = tmp_path / f"{case}.bvh"
    path.write_bytes(body if isinstance(body, bytes) else body.encode())
    with pytest.raises(BVHError) as err:
        read_bvh(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)) and words in msg, msg
    assert err.value.__cause__ is None and (err.value.__context__ is None or err.value.__suppress_context__)
    if line is not None:
        assert err.value.line == line, msg
        assert msg.startswith(f"{path}:{line}: ")
