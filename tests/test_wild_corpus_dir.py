"""Where the wild STEP corpus is found (benchmarks/wild_corpus.py), whatever the checkout's folder."""

from __future__ import annotations

from benchmarks.wild_corpus import WILD_ENV, wild_corpus_dir


def test_the_folder_named_by_the_environment_comes_first(tmp_path, monkeypatch):
    monkeypatch.setenv(WILD_ENV, str(tmp_path))
    assert wild_corpus_dir(tmp_path / "clone") == tmp_path


def test_a_clone_with_no_shared_folder_anywhere_finds_none(tmp_path, monkeypatch):
    monkeypatch.delenv(WILD_ENV, raising=False)
    (tmp_path / "clone").mkdir()
    assert wild_corpus_dir(tmp_path / "clone") is None


def test_a_checkout_beside_the_shared_folder_finds_it(tmp_path, monkeypatch):
    (tmp_path / "shared" / "wild").mkdir(parents=True)
    monkeypatch.delenv(WILD_ENV, raising=False)
    assert wild_corpus_dir(tmp_path / "clone") == tmp_path / "shared" / "wild"


def test_a_worktree_away_from_the_shared_folder_finds_the_one_beside_its_main_checkout(tmp_path, monkeypatch):
    # the layout git writes: main/.git/worktrees/tree (commondir "../..") and the worktree's .git file
    (tmp_path / "work" / "shared" / "wild").mkdir(parents=True)
    gitdir = tmp_path / "work" / "main" / ".git" / "worktrees" / "tree"
    gitdir.mkdir(parents=True)
    (gitdir / "commondir").write_text("../..\n")
    tree = tmp_path / "elsewhere" / "tree"
    tree.mkdir(parents=True)
    (tree / ".git").write_text(f"gitdir: {gitdir}\n")
    monkeypatch.delenv(WILD_ENV, raising=False)
    assert wild_corpus_dir(tree) == tmp_path / "work" / "shared" / "wild"
