"""docs/blocks.md documents every block of the registry: its keys and defaults, its output
(ports, width, units) and a snippet that uses it."""

from pathlib import Path

from odelab.systems.diagram.blocks import BLOCKS, REQUIRED

PAGE = Path(__file__).resolve().parents[3] / "docs" / "blocks.md"


def _section(text, name):
    assert f"#### `{name}`" in text, f"docs/blocks.md has no section for the block {name!r}"
    return text.split(f"#### `{name}`", 1)[1].split("\n#### ", 1)[0].split("\n## ", 1)[0]


def test_every_block_and_key_is_in_docs_blocks_md():
    text = PAGE.read_text()
    for name, cls in BLOCKS.items():
        section = _section(text, name)
        for key, spec in cls.KEYS.items():
            row = next((line for line in section.splitlines() if line.startswith(f"| `{key}` |")), None)
            assert row is not None, f"{name}.{key}"
            if spec.default is REQUIRED:
                assert "| required |" in row, f"{name}.{key}"


def test_every_block_says_its_inputs_and_output_and_has_a_snippet():
    text = PAGE.read_text()
    for name in BLOCKS:
        section = _section(text, name)
        assert "\nInputs: " in section and "\nOutput: " in section, f"{name}: the Inputs: and Output: lines"
        snippets = [part.split("```", 1)[0] for part in section.split("```toml\n")[1:]]
        assert any(f'type = "{name}"' in s for s in snippets), f"{name}: a ```toml snippet with type = \"{name}\""
