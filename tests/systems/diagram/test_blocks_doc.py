"""docs/blocks.md documents every block of the registry with each of its keys and defaults."""

from pathlib import Path

from odelab.systems.diagram.blocks import BLOCKS, REQUIRED

PAGE = Path(__file__).resolve().parents[3] / "docs" / "blocks.md"


def test_every_block_and_key_is_in_docs_blocks_md():
    text = PAGE.read_text()
    for name, cls in BLOCKS.items():
        assert f"#### `{name}`" in text, name
        section = text.split(f"#### `{name}`", 1)[1].split("#### ", 1)[0]
        for key, spec in cls.KEYS.items():
            row = next((line for line in section.splitlines() if line.startswith(f"| `{key}` |")), None)
            assert row is not None, f"{name}.{key}"
            if spec.default is REQUIRED:
                assert "| required |" in row, f"{name}.{key}"
