"""cache.py: where the package keeps what it measured and compiled."""

from __future__ import annotations

from pathlib import Path

from expertise_irl.cache import user_cache_dir


def test_the_cache_follows_xdg_cache_home(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert user_cache_dir() == tmp_path / "expertise-irl"
    assert not user_cache_dir().exists()  # named, not created


def test_without_xdg_cache_home_the_cache_is_under_the_home_folder(monkeypatch, tmp_path):
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert user_cache_dir() == Path(tmp_path) / ".cache" / "expertise-irl"
