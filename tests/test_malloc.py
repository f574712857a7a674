"""The faster malloc the ``inbetween`` command restarts under (:mod:`inbetween_jax.malloc`)."""
import os
import subprocess
import sys

import pytest

from inbetween_jax import malloc

FOUND = ("/usr/lib/libfast.so.1", {"MALLOC_CONF": "dirty_decay_ms:-1"})


def test_preload_env_adds_the_library_once_and_keeps_the_users_settings():
    env = malloc.preload_env({"PATH": "/bin", "MALLOC_CONF": "narenas:2"}, found=FOUND)
    assert env["LD_PRELOAD"] == "/usr/lib/libfast.so.1" and env[malloc.MARK_ENV] == "/usr/lib/libfast.so.1"
    assert env["MALLOC_CONF"] == "narenas:2" and env["PATH"] == "/bin"
    assert malloc.preload_env(env, found=FOUND) is None                       # the restarted process: no loop
    assert malloc.preload_env({}, found=FOUND)["MALLOC_CONF"] == "dirty_decay_ms:-1"


@pytest.mark.parametrize("environ, found", [({malloc.OPT_OUT_ENV: "system"}, FOUND),      # asked for glibc's
                                            ({"LD_PRELOAD": "libother.so"}, FOUND),         # the user's preload
                                            ({}, ())])                                      # nothing installed
def test_preload_env_leaves_the_process_alone(environ, found):
    assert malloc.preload_env(environ, found=found) is None


def _elf(path, kind_of=sys.executable, flip_class=False):
    """A file with the header of ``kind_of`` (the running interpreter: a library it could load), or with its
    ELF class flipped (a 32-bit copy on a 64-bit machine, or the reverse)."""
    head = bytearray(open(kind_of, "rb").read(64))
    if flip_class:
        head[4] = 3 - head[4]
    path.write_bytes(bytes(head))


def test_find_looks_for_the_libraries_in_the_given_folders(tmp_path):
    assert malloc.find(dirs=(str(tmp_path),)) is None
    _elf(tmp_path / "libjemalloc.so.2")
    path, env = malloc.find(dirs=(str(tmp_path),))
    assert path == str(tmp_path / "libjemalloc.so.2") and env["MALLOC_CONF"].startswith("dirty_decay_ms:-1")
    _elf(tmp_path / "libtcmalloc_minimal.so.4")
    assert malloc.find(dirs=(str(tmp_path),)) == (str(tmp_path / "libtcmalloc_minimal.so.4"), {})   # tcmalloc first


def test_find_passes_over_a_library_the_interpreter_cannot_load(tmp_path):
    other, own = tmp_path / "lib32", tmp_path / "lib64"
    other.mkdir()
    own.mkdir()
    _elf(other / "libtcmalloc_minimal.so.4", flip_class=True)          # another ELF class: skipped
    (other / "libjemalloc.so.2").write_bytes(b"not an ELF file")        # not ELF: skipped
    assert malloc.find(dirs=(str(other),)) is None
    _elf(own / "libjemalloc.so.2")
    assert malloc.find(dirs=(str(other), str(own)))[0] == str(own / "libjemalloc.so.2")
    kind = malloc.elf_kind(sys.executable)
    assert kind is not None and malloc.elf_kind(str(other / "libtcmalloc_minimal.so.4"))[0] == 3 - kind[0]


def _run(code: str, **env):
    base = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", malloc.MARK_ENV, malloc.OPT_OUT_ENV)}
    out = subprocess.run([sys.executable, "-c", code, "arg one", "--two"], capture_output=True, text=True,
                         env={**base, **env}, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.split("\n")


CODE = ("import sys\nfrom inbetween_jax import malloc\nmalloc.reexec()\nprint(sys.argv[1:])\n"
        "import os\nname = os.path.basename(malloc.find()[0]).split('.so')[0]\nprint(sum(name in line for line in open('/proc/self/maps')))")


@pytest.mark.skipif(malloc.find() is None or not os.path.exists("/proc/self/maps"),
                    reason="no tcmalloc / jemalloc on this machine (or no /proc)")
def test_reexec_restarts_the_same_command_with_the_library_mapped():
    argv, mapped = _run(CODE)[:2]
    assert argv == "['arg one', '--two']"
    assert int(mapped) > 0                                   # the preloaded library is in the process's memory map
    argv, mapped = _run(CODE, **{malloc.OPT_OUT_ENV: "system"})[:2]
    assert argv == "['arg one', '--two']" and int(mapped) == 0
