"""docs/experiments.md states the verdict rules exactly as the reports print them."""

from __future__ import annotations

from pathlib import Path

from expertise_irl.experiments.report.claims import RULES, VERDICT_NOTES

DOCS = Path(__file__).resolve().parents[2] / "docs" / "experiments.md"


def test_every_rule_and_verdict_note_is_in_the_docs_word_for_word():
    text = DOCS.read_text(encoding="utf-8")
    for kind, rule in RULES.items():
        assert f"- **{kind}**: {rule}\n" in text, kind
    for note in VERDICT_NOTES.values():
        assert f"- {note}\n" in text, note[:40]
