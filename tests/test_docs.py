"""The documentation stays true: the generated config reference, the README's promises, links."""

from __future__ import annotations

import re
import subprocess
import tomllib
from pathlib import Path

from hilnav.config import default_toml_path
from hilnav.config.reference import reference, toml_comments
from tests.conftest import HILNAV, ROOT, hilnav_env


def test_committed_configuration_reference_equals_the_generator():
    committed = (ROOT / "docs" / "configuration.md").read_text(encoding="utf-8")
    assert committed == reference(), (
        "docs/configuration.md is stale: run `hilnav config reference > docs/configuration.md`"
    )


def test_committed_interfaces_page_equals_the_generator():
    from hilnav.interfaces_doc import reference as interfaces

    committed = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8")
    assert committed == interfaces(), (
        "docs/interfaces.md is stale: run `python -m hilnav.interfaces_doc > docs/interfaces.md`"
    )


def test_cli_prints_the_reference():
    res = subprocess.run(
        [*HILNAV, "config", "reference"],
        capture_output=True, text=True, env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert res.stdout == reference()


def _tables(data: dict, prefix: str = "") -> dict[str, dict]:
    """Section name -> its non-table keys, for parsed TOML."""
    leaves = {k: v for k, v in data.items() if not isinstance(v, dict)}
    out = {prefix: leaves} if leaves else {}
    for k, v in data.items():
        if isinstance(v, dict):
            out.update(_tables(v, f"{prefix}.{k}" if prefix else k))
    return out


def test_every_key_and_comment_of_the_example_file_is_in_the_reference():
    text = default_toml_path().read_text(encoding="utf-8")
    doc = reference()
    for section, keys in _tables(tomllib.loads(text)).items():
        heading = f"## [{section}]" if section else "## Top-level keys"
        assert heading in doc, heading
        part = doc.split(heading, 1)[1].split("\n## ", 1)[0]
        for key in keys:
            assert f"| `{key}` |" in part, (section, key)
    for (section, key), comment in toml_comments(text).keys.items():
        assert comment.replace("<", "&lt;") in doc, (section, key, comment)


def test_readme_keeps_the_two_quickstart_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "python3 -m pip install -e . && python3 -m hilnav demo" in readme
    assert 'python3 -m pip install -e ".[test]" && python3 -m pytest' in readme


def _anchors(page: Path) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation dropped, - for spaces."""
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    heads = re.findall(r"^#+ (.+)$", text, flags=re.M)
    return {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in heads}


def test_relative_links_of_the_docs_resolve():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    for page in pages:
        text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue  # a URL
            file, _, anchor = target.partition("#")
            path = (page.parent / file).resolve() if file else page
            where = f"{page.relative_to(ROOT)}: broken link {target}"
            assert path.exists(), where
            if anchor and path.suffix == ".md":
                assert anchor in _anchors(path), where
