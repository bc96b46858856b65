"""The command tables of ``python -m handin``, ``python -m kit`` and ``python -m autograder``:
every command is listed, and one whose optional package is missing says so when run."""

from __future__ import annotations

import importlib.util

import pytest

from core import commands
from core.commands import Command

ENTRY_POINTS = ("handin", "kit", "autograder")


def _table(package):
    return importlib.import_module(f"{package}.__main__").COMMANDS


@pytest.mark.parametrize("package", ENTRY_POINTS)
def test_every_command_points_at_a_real_function(package):
    for name, cmd in _table(package).items():
        assert isinstance(cmd, Command) and cmd.help, name
        module = importlib.import_module(cmd.module.replace("__main__", f"{package}.__main__")
                                         if cmd.module == "__main__" else cmd.module)
        if cmd.register:
            assert callable(getattr(module, cmd.register)), name
        else:
            assert callable(getattr(module, cmd.function)), name
            assert cmd.arguments is None or callable(getattr(module, cmd.arguments)), name


def _hide(monkeypatch, *packages):
    real = importlib.util.find_spec

    def find_spec(name, *args, **kwargs):
        if name.split(".")[0] in packages:
            return None
        return real(name, *args, **kwargs)

    monkeypatch.setattr(commands.importlib.util, "find_spec", find_spec)


def test_a_missing_optional_package_is_listed_and_named_when_run(monkeypatch, capsys):
    from handin.__main__ import main

    _hide(monkeypatch, "nbconvert")
    with pytest.raises(SystemExit):
        main(["--help"])
    listing = capsys.readouterr().out
    assert "pdf" in listing and "needs nbconvert" in listing and "zip" in listing
    assert main(["pdf", "notebooks", "--out", "x.pdf"]) == 2
    err = capsys.readouterr().err
    assert "nbconvert" in err and "pip install nbconvert" in err and "`python -m handin pdf`" in err


def test_kit_commands_stay_listed_when_their_packages_are_missing(monkeypatch, capsys):
    from kit.__main__ import main

    _hide(monkeypatch, "matplotlib", "scipy")
    with pytest.raises(SystemExit):
        main(["--help"])
    listing = capsys.readouterr().out
    assert all(name in listing for name in ("run", "data", "notebooks", "release"))
    assert main(["run", "--out", "nowhere"]) == 2
    assert "scipy, matplotlib" in capsys.readouterr().err


def test_only_the_chosen_command_is_imported(monkeypatch, capsys):
    table = {"good": Command("json", "dumps", "fine", arguments=None),
             "broken": Command("no_such_module_anywhere", "main", "its module does not exist")}
    # Listing every command imports none of them; running one imports only its module.
    with pytest.raises(SystemExit):
        commands.run("prog", "test", table, ["--help"])
    assert "broken" in capsys.readouterr().out
    with pytest.raises(ModuleNotFoundError):  # a broken module is loud, never silently dropped
        commands.run("prog", "test", table, ["broken"])


def test_handin_zip_runs(tmp_path, capsys):
    from handin.__main__ import main

    code = main(["zip", "notebooks", "--out", str(tmp_path / "hw4_code.zip")])
    assert (tmp_path / "hw4_code.zip").is_file() and code == 1  # the student notebooks are stubs
    assert "still a stub" in capsys.readouterr().out
