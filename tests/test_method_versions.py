"""A method's source cannot change without its ``version`` (asv-style source hashes, methods/VERSIONS.toml).

Stored results are reused by (method, version): a change that alters a method's output without a
version bump would silently mix old and new numbers. The first test is the guard; the others check
that the guard sees what it must (private helpers, lazy imports) and says what to do.
"""

from __future__ import annotations

import dataclasses

import pytest

from dpcbench.methods import versions
from dpcbench.methods.registry import METHODS


def test_recorded_versions_and_hashes_match_the_sources():
    found = versions.problems(versions.current(), versions.recorded())
    assert not found, "methods/VERSIONS.toml is out of date:\n" + "\n".join(found)


def test_every_registered_method_is_recorded():
    assert set(versions.recorded()) == set(METHODS.builtin_names())


def test_source_files_follow_private_helpers_and_lazy_imports():
    graph = versions.source_files("temporal-graph")
    assert "methods/temporal_graph.py" in graph
    for helper in ("methods/_cubes.py", "methods/_graph.py", "methods/_registration.py"):
        assert helper in graph
    assert "methods/base.py" not in graph and "methods/registry.py" not in graph
    # temporal-fusion shares the registration helper with temporal-graph
    assert "methods/_registration.py" in versions.source_files("temporal-fusion")
    assert versions.source_files("none") == ["methods/_geometry.py", "methods/reference.py"]
    # a method that is a package: its __init__ and every stage module it imports, not another method's module
    fusion = versions.source_files("temporal-fusion")
    assert "methods/temporal_fusion/__init__.py" in fusion and "methods/temporal_fusion/spatial.py" in fusion
    assert "methods/reference.py" not in fusion and "methods/_geometry.py" in fusion
    with pytest.raises(KeyError, match="unknown method"):
        versions.source_files("no-such-method")


def test_an_import_inside_a_function_is_followed(tmp_path, monkeypatch):
    (tmp_path / "a.py").write_text("def fill():\n    from dpcbench.methods.b import helper\n    return helper\n")
    (tmp_path / "b.py").write_text("def helper():\n    return 1\n")
    monkeypatch.setattr(versions, "PACKAGE_DIR", tmp_path)
    assert versions._imported_methods_modules("dpcbench.methods.a") == {"dpcbench.methods.b"}


def test_source_hash_depends_on_content_and_path(tmp_path, monkeypatch):
    monkeypatch.setattr(versions, "ROOT", tmp_path)
    (tmp_path / "a.py").write_bytes(b"x = 1\n")
    (tmp_path / "b.py").write_bytes(b"x = 1\r\n")
    first = versions.source_hash(["a.py"])
    assert versions.source_hash(["b.py"]) != first  # the path is part of what is hashed
    assert versions.source_hash(["a.py"]) == first
    (tmp_path / "a.py").write_bytes(b"x = 2\n")
    assert versions.source_hash(["a.py"]) != first
    (tmp_path / "a.py").write_bytes(b"x = 1\r\n")  # only the line endings differ: same hash
    assert versions.source_hash(["a.py"]) == first


def test_a_changed_source_without_a_bump_fails_with_the_command_to_run():
    now = versions.current()
    stored = dict(now)
    old = now["lozes-pde"]
    stored["lozes-pde"] = dataclasses.replace(old, sha256="0" * 64)
    (message,) = versions.problems(now, stored)
    assert message.startswith("lozes-pde: the source") and f"version is still {old.version}" in message
    assert "bump version and update the hash with `python -m dpcbench.methods.versions --update`" in message

    stored["lozes-pde"] = dataclasses.replace(old, sha256="0" * 64, version="0")  # bumped, hash not updated
    (message,) = versions.problems(now, stored)
    assert f"version 0 -> {old.version}" in message and "update the hash" in message

    stored = {k: v for k, v in now.items() if k != "meshlab"}
    stored["gone"] = old
    assert versions.problems(now, stored) == [
        "gone: recorded in methods/VERSIONS.toml but no longer registered; drop it with "
        "`python -m dpcbench.methods.versions --update`",
        "meshlab: not recorded in methods/VERSIONS.toml; record it with `python -m dpcbench.methods.versions --update`",
    ]


def test_update_round_trip_and_refusal_without_a_bump(tmp_path):
    path = tmp_path / "VERSIONS.toml"
    changes = versions.update(path=path)
    assert len(changes) == len(METHODS.builtin_names())
    assert versions.recorded(path) == versions.current()
    assert versions.update(path=path) == []  # nothing changed: nothing reported

    text = path.read_text()
    meshlab = versions.current()["meshlab"]
    sha = meshlab.sha256
    path.write_text(text.replace(sha, "f" * 64, 1))  # as if meshlab's source had changed since
    with pytest.raises(ValueError, match="meshlab changed but the version did not"):
        versions.update(path=path)
    assert "f" * 64 in path.read_text()  # a refused update writes nothing
    assert versions.update(same_output=True, path=path) == [
        f"meshlab: version {meshlab.version}, sha256 {sha[:12]}, {len(meshlab.files)} file(s)"]
    assert versions.recorded(path) == versions.current()


def test_check_command_exit_status(capsys):
    assert versions.main(["--check"]) == 0
    assert "up to date" in capsys.readouterr().out
