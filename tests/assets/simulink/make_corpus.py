"""Writes this folder's Simulink models: the project's own files with the constructs of real course models.

Run from the repository root: ``python tests/assets/simulink/make_corpus.py``. Each model is described
once (blocks, lines, masks, solver settings, callbacks) and written in the format its name says: a
classic ``.mdl``, a text-package ``.mdl`` (``__MWOPC_PACKAGE_BEGIN__``), an ``.slx`` in the newer layout
(``simulink/systems/system_*.xml``, lines by SID) or in the older one (everything in
``simulink/blockdiagram.xml``, lines by block name). See SOURCES.md for why they are written here.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape

HERE = Path(__file__).resolve().parent


class Sub:
    """A subsystem's contents: blocks, lines and (masked) its mask parameters."""

    def __init__(self, blocks, lines, mask=()):
        self.blocks, self.lines, self.mask = blocks, lines, list(mask)


def B(kind, name, params=None, sub=None, source=None, ports=None):  # noqa: N802 - a block, briefly
    return {"type": kind, "name": name, "params": dict(params or {}), "sub": sub, "source": source, "ports": ports}


def L(src, dsts, name=""):  # noqa: N802 - a line: "Block:1" -> ["Block:2", ...]
    return {"src": src, "dsts": dsts if isinstance(dsts, list) else [dsts], "name": name}


def _split(end):
    name, _, port = end.rpartition(":")
    return name, port


# --- the classic .mdl ---------------------------------------------------------------------------------

def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _mdl_system(sub, name, indent, sid):
    pad = "  " * indent
    out = [f"{pad}System {{", f"{pad}  Name {_q(name)}"]
    for block in sub.blocks:
        sid[0] += 1
        out.append(f"{pad}  Block {{")
        out.append(f"{pad}    BlockType {block['type']}")
        out.append(f"{pad}    Name {_q(block['name'])}")
        out.append(f"{pad}    SID {_q(str(sid[0]))}")
        if block["ports"]:
            out.append(f"{pad}    Ports [{block['ports'][0]}, {block['ports'][1]}]")
        if block["source"]:
            out.append(f"{pad}    SourceBlock {_q(block['source'])}")
        for key, value in block["params"].items():
            out.append(f"{pad}    {key} {_q(value)}")
        inner = block["sub"]
        if inner is not None:
            if inner.mask:
                out.append(f"{pad}    Mask on")
                out.append(f"{pad}    MaskPromptString {_q('|'.join(n for n, _ in inner.mask))}")
                out.append(f"{pad}    MaskVariables {_q(''.join(f'{n}=@{i + 1};' for i, (n, _) in enumerate(inner.mask)))}")
                out.append(f"{pad}    MaskValueString {_q('|'.join(v for _, v in inner.mask))}")
            out.extend(_mdl_system(inner, block["name"], indent + 2, sid))
        out.append(f"{pad}  }}")
    for line in sub.lines:
        src, sport = _split(line["src"])
        out.append(f"{pad}  Line {{")
        if line["name"]:
            out.append(f"{pad}    Name {_q(line['name'])}")
        out.append(f"{pad}    SrcBlock {_q(src)}")
        out.append(f"{pad}    SrcPort {sport}")
        if len(line["dsts"]) == 1:
            dst, dport = _split(line["dsts"][0])
            out.append(f"{pad}    DstBlock {_q(dst)}")
            out.append(f"{pad}    DstPort {dport}")
        else:
            for end in line["dsts"]:
                dst, dport = _split(end)
                out += [f"{pad}    Branch {{", f"{pad}      DstBlock {_q(dst)}", f"{pad}      DstPort {dport}",
                        f"{pad}    }}"]
        out.append(f"{pad}  }}")
    out.append(f"{pad}}}")
    return out


def classic_mdl(name, root, solver, model_params=None):
    out = ["# A classic Simulink model file (text), written by make_corpus.py", "Model {", f"  Name {_q(name)}",
           "  Version 7.9"]
    for key, value in (model_params or {}).items():
        out.append(f"  {key} {_q(value)}")
    out += ["  Array {", '    Type "Handle"', "    Dimension 1", "    Simulink.ConfigSet {", "      $ObjectID 1",
            "      Array {", '        Type "Handle"', "        Dimension 1", "        Simulink.SolverCC {",
            "          $ObjectID 2"]
    out += [f"          {k} {_q(v)}" for k, v in solver.items()]
    out += ["        }", "      }", "    }", "  }"]
    out += _mdl_system(root, name, 1, [0])
    out.append("}")
    return "\n".join(out) + "\n"


# --- XML (.slx and the text package) ------------------------------------------------------------------

def _p(key, value):
    return f'<P Name="{escape(key)}">{escape(value)}</P>'


def _xml_block(block, sid, refs, inline, parts):
    attrs = f'BlockType="{block["type"]}" Name="{escape(block["name"], {chr(34): "&quot;"})}" SID="{sid}"'
    body = []
    if block["ports"]:
        body.append(_p("Ports", f"[{block['ports'][0]}, {block['ports'][1]}]"))
    if block["source"]:
        body.append(_p("SourceBlock", block["source"]))
        body.append("<InstanceData>" + "".join(_p(k, v) for k, v in block["params"].items()) + "</InstanceData>")
    else:
        body += [_p(k, v) for k, v in block["params"].items()]
    inner = block["sub"]
    if inner is not None:
        if inner.mask:
            body.append("<Mask>" + "".join(f'<MaskParameter Name="{n}" Type="edit"><Prompt>{n}</Prompt>'
                                           f"<Value>{escape(v)}</Value></MaskParameter>" for n, v in inner.mask)
                        + "</Mask>")
        body.append(_xml_system(inner, refs, inline, parts) if inline else f'<System Ref="system_{sid}"/>')
        if not inline:
            parts[f"simulink/systems/system_{sid}.xml"] = _xml_system(inner, refs, inline, parts, top=True)
    return f"<Block {attrs}>" + "".join(body) + "</Block>"


def _xml_system(sub, refs, inline, parts, top=False):
    ids = {}
    blocks = []
    for block in sub.blocks:
        refs[0] += 1
        ids[block["name"]] = refs[0]
    for block in sub.blocks:
        blocks.append(_xml_block(block, ids[block["name"]], refs, inline, parts))
    lines = []
    for line in sub.lines:
        src, sport = _split(line["src"])
        name = _p("Name", line["name"]) if line["name"] else ""
        if inline:  # the older layout: lines by block name
            head = _p("SrcBlock", src) + _p("SrcPort", sport)
            ends = [(_p("DstBlock", _split(d)[0]) + _p("DstPort", _split(d)[1])) for d in line["dsts"]]
        else:
            head = _p("Src", f"{ids[src]}#out:{sport}")
            ends = [_p("Dst", f"{ids[_split(d)[0]]}#in:{_split(d)[1]}") for d in line["dsts"]]
        body = ends[0] if len(ends) == 1 else "".join(f"<Branch>{e}</Branch>" for e in ends)
        lines.append(f"<Line>{name}{head}{body}</Line>")
    xml = "<System>" + "".join(blocks) + "".join(lines) + "</System>"
    return ('<?xml version="1.0" encoding="utf-8"?>\n' + xml) if top else xml


def _config(solver):
    return ('<?xml version="1.0" encoding="utf-8"?>\n<ConfigSet><Object PropName="ConfigurationSets" ObjectID="1" '
            'ClassName="Simulink.ConfigSet"><Array PropName="Components" Type="Handle" Dimension="1">'
            '<Object PropName="Components" ObjectID="2" ClassName="Simulink.SolverCC">'
            + "".join(_p(k, v) for k, v in solver.items()) + "</Object></Array></Object></ConfigSet>")


def xml_parts(name, root, solver, model_params=None, inline=False):
    parts: dict[str, str] = {}
    refs = [0]
    params = "".join(_p(k, v) for k, v in (model_params or {}).items())
    if inline:
        config = _config(solver).split("\n", 1)[1].replace("<ConfigSet>", "").replace("</ConfigSet>", "")
        model = (f'<Model Name="{name}">{_p("Version", "8.0")}{params}<Array PropName="ConfigurationSets" '
                 f'Type="Handle" Dimension="1">{config}</Array>{_xml_system(root, refs, True, parts)}</Model>')
    else:
        model = f'<Model Name="{name}">{_p("Version", "10.4")}{params}<System Ref="system_root"/></Model>'
        parts["simulink/systems/system_root.xml"] = _xml_system(root, refs, False, parts, top=True)
        parts["simulink/configSet0.xml"] = _config(solver)
    parts["simulink/blockdiagram.xml"] = ('<?xml version="1.0" encoding="utf-8"?>\n<ModelInformation Version="1.0">'
                                          + model + "</ModelInformation>")
    return parts


def slx(name, root, solver, model_params=None, inline=False) -> bytes:
    parts = xml_parts(name, root, solver, model_params, inline)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("[Content_Types].xml", '<?xml version="1.0" encoding="utf-8"?><Types xmlns="http://schemas.'
                    'openxmlformats.org/package/2006/content-types"><Default Extension="xml" ContentType='
                    '"application/vnd.mathworks.simulink.model+xml"/></Types>')
        zf.writestr("_rels/.rels", '<?xml version="1.0" encoding="utf-8"?><Relationships/>')
        zf.writestr("metadata/coreProperties.xml", '<?xml version="1.0" encoding="utf-8"?><coreProperties/>')
        for part, text in parts.items():
            zf.writestr(part, text)
    return buf.getvalue()


def text_package(name, root, solver, model_params=None) -> str:
    parts = xml_parts(name, root, solver, model_params)
    out = ["# MathWorks OPC Text Package", "Model {", "  Version 10.4", '  Description "Simulink model saved in '
           'R2021b"', "}", "__MWOPC_PACKAGE_BEGIN__ R2021b"]
    for part, text in parts.items():
        out.append(f"__MWOPC_PART_BEGIN__ /{part}")
        out.append(text)
    out.append("__MWOPC_PACKAGE_END__")
    return "\n".join(out) + "\n"


def write(filename, root, solver, model_params=None, layout=None):
    path = HERE / filename
    path.parent.mkdir(exist_ok=True)
    name = path.stem
    if filename.endswith(".slx"):
        path.write_bytes(slx(name, root, solver, model_params, inline=layout == "blockdiagram"))
    elif layout == "package":
        path.write_text(text_package(name, root, solver, model_params))
    else:
        path.write_text(classic_mdl(name, root, solver, model_params))


if __name__ == "__main__":
    from models import MODELS  # noqa: E402 - the descriptions, beside this file

    for filename, (root, solver, params, layout) in MODELS.items():
        write(filename, root, solver, params, layout)
        print("wrote", filename)
