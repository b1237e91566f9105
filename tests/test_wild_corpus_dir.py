"""Where the wild STEP corpus is found (benchmarks/wild_corpus.py), whatever the checkout's folder."""

from __future__ import annotations

from benchmarks import wild_corpus
from benchmarks.wild_corpus import WILD_ENV, wild_corpus_dir


def test_the_folder_named_by_the_environment_comes_first(tmp_path, monkeypatch):
    monkeypatch.setenv(WILD_ENV, str(tmp_path))
    assert wild_corpus_dir() == tmp_path


def test_a_clone_with_no_shared_folder_anywhere_finds_none(tmp_path, monkeypatch):
    # a clone at tmp_path/clone has no ../shared/wild; with /work/shared/wild absent too, None
    monkeypatch.delenv(WILD_ENV, raising=False)
    monkeypatch.setattr(wild_corpus, "ROOT", tmp_path / "clone")
    monkeypatch.setattr(wild_corpus, "SHARED_WILD", tmp_path / "absent")
    assert wild_corpus_dir() is None


def test_a_checkout_beside_the_shared_folder_finds_it(tmp_path, monkeypatch):
    (tmp_path / "shared" / "wild").mkdir(parents=True)
    monkeypatch.delenv(WILD_ENV, raising=False)
    monkeypatch.setattr(wild_corpus, "ROOT", tmp_path / "clone")
    monkeypatch.setattr(wild_corpus, "SHARED_WILD", tmp_path / "absent")
    assert wild_corpus_dir() == tmp_path / "shared" / "wild"


def test_a_worktree_away_from_the_shared_folder_finds_the_workplaces_one(tmp_path, monkeypatch):
    (tmp_path / "work" / "shared" / "wild").mkdir(parents=True)
    monkeypatch.delenv(WILD_ENV, raising=False)
    monkeypatch.setattr(wild_corpus, "ROOT", tmp_path / "work" / "wt" / "tree")
    monkeypatch.setattr(wild_corpus, "SHARED_WILD", tmp_path / "work" / "shared" / "wild")
    assert wild_corpus_dir() == tmp_path / "work" / "shared" / "wild"
