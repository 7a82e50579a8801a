"""What every command shares: --version, lazy imports, common flags, help texts, exit codes, the
compilation cache set-up."""

import argparse
import os
import subprocess
import sys

import pytest

from diffguide.cli import _COMMANDS, build_parser, main
from diffguide.cli._common import MESH_COMMANDS, cache_dir, normalise_mesh, parse_mesh_text


def _sub(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def test_version_and_help_import_neither_jax_nor_matplotlib():
    code = (
        "import sys, contextlib, io\n"
        "from diffguide.cli import main\n"
        "for argv in (['--version'], ['--help'], ['fit', '--help'], ['simulate', '--help'],"
        " ['montecarlo', '--help'], ['import', '--help']):\n"
        "    with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "        try:\n"
        "            main(argv)\n"
        "        except SystemExit as e:\n"
        "            assert e.code == 0, (argv, e.code)\n"
        "    assert out.getvalue().strip(), argv\n"
        "print(sorted(m for m in ('jax', 'jaxlib', 'equinox', 'matplotlib') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout


def test_version_names_the_stack(capsys):
    import diffguide

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"diffguide {diffguide.__version__} (jax ")
    assert "\n" not in line


@pytest.mark.parametrize("name", _COMMANDS)
def test_every_command_has_the_common_flags_and_clean_help(name):
    p = _sub(name)
    flags = p._option_string_actions
    assert "--quiet" in flags and "-q" in flags and "--cache-dir" in flags and "--no-cache" in flags
    assert flags["-q"] is flags["--quiet"]
    assert ("--mesh" in flags) == (name in MESH_COMMANDS)
    text = p.format_help()
    assert "(default: None)" not in text
    assert not any(line.strip().startswith("--nx") for line in text.splitlines())
    for line in text.splitlines():
        assert line.lower().count("default") <= 1, line
    assert "exit status:" in text and "3  a solve did not converge" in text


def test_mesh_option_and_no_nx_ny():
    assert parse_mesh_text("20x10") == (20, 10)
    for bad in ("20", "0x10", "ax3", "20x10x1"):
        with pytest.raises(ValueError, match="--mesh"):
            parse_mesh_text(bad)
    args = argparse.Namespace(mesh="12x6", nx=None, ny=None)
    normalise_mesh(args, "fit")
    assert (args.nx, args.ny) == (12, 6)
    args = argparse.Namespace(mesh=None)
    normalise_mesh(args, "table")
    assert (args.nx, args.ny) == (None, None)  # the machine's own mesh
    for name in MESH_COMMANDS:  # the 0.1 spellings --nx/--ny are gone
        flags = _sub(name)._option_string_actions
        assert "--nx" not in flags and "--ny" not in flags, name


def test_cache_dir_choice(monkeypatch, tmp_path):
    monkeypatch.delenv("DIFFGUIDE_CACHE_DIR", raising=False)
    ns = argparse.Namespace
    assert str(cache_dir(ns(cache_dir=None, no_cache=False))).endswith(".cache/diffguide/jax")
    monkeypatch.setenv("DIFFGUIDE_CACHE_DIR", str(tmp_path / "env"))
    assert cache_dir(ns(cache_dir=None, no_cache=False)) == tmp_path / "env"
    assert cache_dir(ns(cache_dir=str(tmp_path / "flag"), no_cache=False)) == tmp_path / "flag"
    assert cache_dir(ns(cache_dir=str(tmp_path), no_cache=True)) is None
    monkeypatch.setenv("DIFFGUIDE_CACHE_DIR", "")
    assert cache_dir(ns(cache_dir=None, no_cache=False)) is None


def test_runtime_setup_in_a_fresh_process(tmp_path):
    code = (
        "import argparse, os\n"
        "from diffguide.cli._common import prepare_runtime\n"
        "prepare_runtime(argparse.Namespace(cache_dir=None, no_cache=False))\n"
        "import jax\n"
        "print(os.environ['EQX_ON_ERROR'], jax.config.jax_compilation_cache_dir,"
        " jax.config.jax_enable_x64)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "EQX_ON_ERROR"}
    env["DIFFGUIDE_CACHE_DIR"] = str(tmp_path / "cache")
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    assert out.stdout.split() == ["nan", str(tmp_path / "cache"), "True"]
    env["EQX_ON_ERROR"] = "raise"  # the user's choice wins
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    assert out.stdout.split()[0] == "raise"


def test_internal_error_exits_1_with_traceback(monkeypatch, capsys):
    import diffguide.cli.config as config_cmd

    def boom(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr(config_cmd, "run", boom)
    assert main(["config", "--no-cache"]) == 1
    err = capsys.readouterr().err
    assert "RuntimeError: a bug" in err and "internal error" in err


def test_montecarlo_mounting_choices_match_the_library():
    from diffguide.cli.montecarlo import MOUNTING_CHOICES
    from diffguide.jobs.study import MOUNTING_CHOICES as STUDY_CHOICES
    from diffguide.studies.random_rails import MOUNTING_CLASSES

    assert set(MOUNTING_CHOICES) == set(MOUNTING_CLASSES) == set(STUDY_CHOICES)


def test_the_command_passes_its_exit_status_and_messages_through_its_quick_exit(tmp_path):
    """``python -m diffguide.cli`` ends with ``os._exit`` after its outputs: the status and
    the message on stderr must still arrive."""
    missing = tmp_path / "none.csv"
    out = subprocess.run(
        [sys.executable, "-m", "diffguide.cli", "fit", "--measurements", str(missing),
         "--out", str(tmp_path / "o"), "--no-cache"],
        capture_output=True, text=True,
    )
    assert out.returncode == 2, out.stderr
    assert "none.csv" in out.stderr and "error" in out.stderr
    assert not (tmp_path / "o").exists()


def test_xla_cpu_flags_only_for_measured_jaxlib_and_never_over_the_users(monkeypatch):
    from importlib.metadata import version

    from diffguide.cli import _common

    monkeypatch.setattr(_common, "XLA_CPU_FLAGS", {version("jaxlib"): ("--a=1", "--b=2")})
    monkeypatch.setenv("XLA_FLAGS", "--b=7 --c")
    _common._set_xla_cpu_flags()
    assert os.environ["XLA_FLAGS"].split() == ["--b=7", "--c", "--a=1"]
    monkeypatch.setattr(_common, "XLA_CPU_FLAGS", {"0.0.0": ("--a=1",)})  # another version
    monkeypatch.delenv("XLA_FLAGS")
    _common._set_xla_cpu_flags()
    assert "XLA_FLAGS" not in os.environ


def test_a_second_run_reads_its_programs_back_without_xla_log_lines(tmp_path):
    """Two fresh processes set up as the command line is, each compiling and running one small
    program: the second reads it from the cache folder, and neither prints XLA's C++ log (on
    CPUs whose compiler tuning flags are not among the host's detected features, XLA logs two
    "could lead to SIGILL" error lines per executable read back; a warning line on every CPU).
    The second run's stdout shows it was read back (one file in the folder, the same bits)."""
    code = (
        "import argparse, os\n"
        "from diffguide.cli._common import prepare_runtime\n"
        "prepare_runtime(argparse.Namespace(cache_dir=None, no_cache=False))\n"
        "import jax, jax.numpy as jnp\n"
        "f = jax.jit(lambda x: jnp.sin(x) @ x + 1.0)\n"
        "print(float(f(jnp.eye(3) * 0.5)[0, 0]).hex())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "TF_CPP_MIN_LOG_LEVEL"}
    env["DIFFGUIDE_CACHE_DIR"] = str(tmp_path / "cache")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True, env=env) for _ in range(2)]
    assert runs[0].stdout == runs[1].stdout
    assert list((tmp_path / "cache").glob("jit_*-cache"))
    for r in runs:
        assert "cpu_aot_loader" not in r.stderr and "pjrt_executable" not in r.stderr, r.stderr
