#!/usr/bin/env python3
"""Extract small parameter metadata tables (name, type, range, values) for firmware-config/.

Two sub-commands, each writing one tab-separated table whose first lines (starting with `#`)
say where and from which commit it was extracted:

  ardupilot --tree DIR --commit SHA [--vehicle ArduCopter] [--prefix P ...] --out FILE
      Runs ArduPilot's own Tools/autotest/param_metadata/param_parse.py (in this process, with
      --no-emit, so nothing is written into the tree) to get every documented parameter of the
      vehicle with its full name, @Range, @Values and @Bitmask. The storage type, which the doc
      comments do not carry, is read from the C++ declarations: each parameter's doc block is
      paired with the AP_GROUPINFO / GSCALAR entry of the same name in its file, and that
      entry's member is looked up in the class's header (AP_Int8 -> int8, AP_Int16 -> int16,
      AP_Int32 -> int32, AP_Float / AP_Vector3f -> float, AP_Enum<..> -> int8,
      AP_Enum16<..> -> int16). A parameter whose declaration is not found gets type `unknown`
      (the checker then checks only that the value is a number).

  px4 --root DIR --commits TEXT [--prefix P ...] --out FILE
      Reads PX4's parameter definitions from a PX4-Autopilot checkout (or a folder holding the
      same files at the same relative paths): src/modules/mavlink/module.yaml (MAV_${i}_*,
      expanded per instance, and MAV_${i}_CONFIG from its serial_config),
      src/modules/mavlink/mavlink_params.yaml (MAV_*), src/modules/gimbal/module.yaml (MNT_*),
      Tools/serial/generate_config.py (the serial port tags and indices, which give the
      SER_<TAG>_BAUD names and the values of MAV_${i}_CONFIG) and
      Tools/serial/serial_params.c.jinja (the allowed baud rates). PX4 types: int32 (also for
      enum and boolean) and float.

Table columns: name, type (int8|int16|int32|float|unknown), min, max (empty if not
documented), values (`KEY:label|KEY:label`, enumerations), bitmask (`BIT:label|...`).

Use (see firmware-config/README.md):
  python3 scripts/firmware_extract_params.py ardupilot --tree ../ardupilot \
      --commit "$(git -C ../ardupilot rev-parse HEAD)" \
      --out firmware-config/metadata/ardupilot-copter-params.tsv
  python3 scripts/firmware_extract_params.py px4 --root ../PX4-Autopilot \
      --commits "$(git -C ../PX4-Autopilot rev-parse HEAD)" \
      --out firmware-config/metadata/px4-params.tsv
"""

import argparse
import ast
import os
import re
import sys
import types

# Parameter groups kept in the tables, as regular expressions matched at the start of the name
# (the tables stay small; the checker refuses names that are not in them, so a file may only
# use parameters of these groups). SERVO: outputs 1-16 (their FUNCTION value lists are long).
ARDUPILOT_PREFIXES = ["SERIAL", "MAV", "MNT1_", "CAM1_", r"SERVO([1-9]|1[0-6])_", "BRD_SER"]
PX4_PREFIXES = ["MAV_", "SER_", "MNT_"]


def wanted(name, prefixes):
    return any(re.match(p, name) for p in prefixes)

AP_TYPES = {
    "AP_Int8": "int8",
    "AP_Int16": "int16",
    "AP_Int32": "int32",
    "AP_Float": "float",
    "AP_Vector3f": "float",
    "AP_Enum": "int8",
    "AP_Enum16": "int16",
}


def clean(text):
    """One line, no tabs or separators that the table uses."""
    return " ".join(str(text).replace("|", "/").split())


def row(name, typ, lo="", hi="", values=(), bitmask=()):
    vals = "|".join(f"{k}:{clean(v)}" for k, v in values)
    bits = "|".join(f"{k}:{clean(v)}" for k, v in bitmask)
    return "\t".join([name, typ, str(lo), str(hi), vals, bits])


def pairs(text):
    """`0:None, 1:Servo` -> [("0", "None"), ("1", "Servo")]."""
    out = []
    for item in text.split(","):
        key, sep, label = item.partition(":")
        if sep and key.strip():
            out.append((key.strip(), label.strip()))
    return out


# --- ArduPilot ---------------------------------------------------------------------------

GROUPINFO = re.compile(
    r"AP_GROUPINFO\w*\(\s*\"(\w+)\"\s*,\s*[^,]+,\s*(\w+)\s*,\s*([^,]+?)\s*,", re.S)
SUBGROUP = re.compile(r"AP_SUBGROUP\w*\(")
GSCALAR = re.compile(r"\b[GA]SCALAR\(\s*(\w+)\s*,\s*\"(\w+)\"")
DECL = r"\b(AP_Int8|AP_Int16|AP_Int32|AP_Float|AP_Vector3f|AP_Enum16|AP_Enum)\b(?:<[^>]*>)?\s+{}\s*[\[;,=]"


def run_param_parse(tree, vehicle):
    """Runs param_parse.py with --no-emit and returns its vehicle and library objects."""
    pm = os.path.join(tree, "Tools", "autotest", "param_metadata")
    script = os.path.join(pm, "param_parse.py")
    sys.dont_write_bytecode = True  # nothing written into the tree
    sys.path.insert(0, pm)
    try:
        import lxml  # noqa: F401  (only its XML emitter needs it; not used with --no-emit)
    except ImportError:
        stub = types.ModuleType("lxml")
        stub.etree = types.ModuleType("lxml.etree")
        sys.modules["lxml"] = stub
        sys.modules["lxml.etree"] = stub.etree
    argv = sys.argv
    sys.argv = [script, "--vehicle", vehicle, "--no-emit"]
    scope = {"__file__": script, "__name__": "__param_parse__"}
    cwd = os.getcwd()
    try:
        with open(script) as f:
            code = compile(f.read(), script, "exec")
        try:
            exec(code, scope)
        except SystemExit:
            pass  # param_parse exits with its error count after validation
    finally:
        sys.argv = argv
        os.chdir(cwd)
    return scope["vehicle"], scope["libraries"]


class SourceIndex:
    """Finds the C++ declaration (and so the storage type) of documented parameters."""

    def __init__(self, tree):
        self.tree = tree
        self.by_base = {}
        self.headers = []
        for sub in ("libraries", "ArduCopter", "ArduPlane", "Rover", "ArduSub"):
            for root, _dirs, files in os.walk(os.path.join(tree, sub)):
                for name in files:
                    path = os.path.join(root, name)
                    self.by_base.setdefault(name, []).append(path)
                    if name.endswith(".h"):
                        self.headers.append(path)
        self.texts = {}

    def text(self, path):
        if path not in self.texts:
            with open(path, errors="replace") as f:
                self.texts[path] = f.read()
        return self.texts[path]

    def entries(self, path):
        """NAME -> (class, member expression) for the AP_GROUPINFO / GSCALAR entries."""
        text = self.text(path)
        out = {}
        for m in GROUPINFO.finditer(text):
            out.setdefault(m.group(1), (m.group(2), m.group(3)))
        for m in GSCALAR.finditer(text):
            out.setdefault(m.group(2), ("Parameters", m.group(1)))
        return out

    def source_file(self, real_path, doc_name):
        """The file a parameter's doc block came from (param_parse keeps the @Path text)."""
        if os.path.isabs(real_path) and os.path.exists(real_path):
            return real_path
        cands = self.by_base.get(os.path.basename(real_path), [])
        for c in cands:
            if re.search(r"@Param(?:\{[^}]*\})?: " + re.escape(doc_name) + r"\b", self.text(c)):
                return c
        return cands[0] if cands else None

    def member_type(self, cls, member, near):
        field = re.split(r"[.\->]+", re.sub(r"\[[^\]]*\]", "", member))[-1].strip()
        decl = re.compile(DECL.format(re.escape(field)))
        # the class's own header first, then any header beside the source file
        class_re = re.compile(r"\b(?:class|struct)\s+" + re.escape(cls) + r"\b[^;{]*\{")
        here = os.path.dirname(near)
        ordered = sorted(self.headers, key=lambda h: (os.path.dirname(h) != here, h))
        for h in ordered:
            text = self.text(h)
            cm = class_re.search(text)
            if not cm:
                continue
            dm = decl.search(text, cm.start())
            if dm:
                return AP_TYPES[dm.group(1)]
        for h in ordered:
            if os.path.dirname(h) != here:
                break
            dm = decl.search(self.text(h))
            if dm:
                return AP_TYPES[dm.group(1)]
        return None

    def param_type(self, real_path, lib_prefix, full_name):
        doc_name = full_name[len(lib_prefix):] if full_name.startswith(lib_prefix) else full_name
        path = self.source_file(real_path, doc_name)
        if path is None:
            return "unknown"
        entries = self.entries(path)
        key = doc_name
        if key not in entries and re.search(r"_[XYZ]$", key):
            key = key[:-2]  # Vector3 parameters: NAME_X/_Y/_Z from one AP_Vector3f NAME
        if key not in entries:
            return "unknown"
        cls, member = entries[key]
        return self.member_type(cls, member, path) or "unknown"


def extract_ardupilot(args):
    vehicle, libraries = run_param_parse(args.tree, args.vehicle)
    index = SourceIndex(args.tree)
    rows = {}
    groups = [("", vehicle.params, True)] + [(lib.name, lib.params, False) for lib in libraries]
    for prefix, params, is_vehicle in groups:
        for p in params:
            name = p.name.split(":")[-1]
            if not wanted(name, args.prefix):
                continue
            if is_vehicle:
                typ = index.param_type(p.real_path, "", name)
            elif getattr(p, "real_path", "").endswith(".lua"):
                typ = "float"  # scripting parameters are floats
            else:
                typ = index.param_type(p.real_path, prefix, name)
            lo = hi = ""
            rng = getattr(p, "Range", "").split()
            if len(rng) == 2:
                lo, hi = rng
            values = pairs(getattr(p, "Values", ""))
            bitmask = pairs(getattr(p, "Bitmask", ""))
            rows.setdefault(name, row(name, typ, lo, hi, values, bitmask))
    header = [
        f"# ArduPilot {args.vehicle} parameter metadata, extracted by "
        "scripts/firmware_extract_params.py",
        f"# from github.com/ArduPilot/ardupilot commit {args.commit}: "
        "Tools/autotest/param_metadata/param_parse.py (names, @Range, @Values, @Bitmask) "
        "and the AP_Int8/AP_Int16/AP_Int32/AP_Float declarations (types)",
        "# groups: " + " ".join(args.prefix),
    ]
    return header, [rows[k] for k in sorted(rows)]


# --- PX4 ---------------------------------------------------------------------------------

def px4_type(d):
    t = d.get("type")
    return "float" if t == "float" else "int32"


def px4_values(d):
    if d.get("type") == "boolean":
        return [("0", "Disabled"), ("1", "Enabled")]
    return [(str(k), v) for k, v in (d.get("values") or {}).items()]


def px4_bitmask(d):
    return [(str(k), v) for k, v in (d.get("bit") or {}).items()]


def px4_definitions(path):
    import yaml

    with open(path) as f:
        doc = yaml.load(f, Loader=yaml.SafeLoader)
    out = []
    for group in doc.get("parameters") or []:
        for name, d in (group.get("definitions") or {}).items():
            n = d.get("num_instances", 1)
            names = [name.replace("${i}", str(i)) for i in range(n)] if "${i}" in name else [name]
            for full in names:
                out.append(row(full, px4_type(d), d.get("min", ""), d.get("max", ""),
                               px4_values(d), px4_bitmask(d)))
    return doc, out


def px4_serial_ports(path):
    """The `serial_ports = {...}` literal of Tools/serial/generate_config.py."""
    with open(path) as f:
        tree = ast.parse(f.read())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "serial_ports" for t in node.targets):
            return ast.literal_eval(node.value)
    raise SystemExit(f"{path}: no serial_ports assignment")


def extract_px4(args):
    root = args.root
    rows = []
    ports = px4_serial_ports(os.path.join(root, "Tools/serial/generate_config.py"))
    with open(os.path.join(root, "Tools/serial/serial_params.c.jinja")) as f:
        jinja = f.read()
    bauds = [(m.group(1), m.group(2)) for m in re.finditer(r"@value (\d+) (.+)", jinja)
             if "serial_device" not in m.group(0)]
    for tag in ports:
        rows.append(row(f"SER_{tag}_BAUD", "int32", values=bauds))
    port_values = [("0", "Disabled")] + [(str(p["index"]), p["label"]) for p in ports.values()]
    port_values.append(("1000", "Ethernet"))  # generate_config.py's ethernet configuration
    for rel in ("src/modules/mavlink/module.yaml", "src/modules/mavlink/mavlink_params.yaml",
                "src/modules/gimbal/module.yaml"):
        doc, defs = px4_definitions(os.path.join(root, rel))
        rows.extend(defs)
        for sc in doc.get("serial_config") or []:
            pc = sc.get("port_config_param")
            if pc:
                for i in range(sc.get("num_instances", 1)):
                    rows.append(row(pc["name"].replace("${i}", str(i)), "int32",
                                    values=port_values))
    rows = [r for r in rows if wanted(r.split("\t", 1)[0], args.prefix)]
    uniq = {r.split("\t", 1)[0]: r for r in rows}
    header = [
        "# PX4 parameter metadata, extracted by scripts/firmware_extract_params.py from "
        "github.com/PX4/PX4-Autopilot",
        f"# sources: {args.commits}",
        "# groups: " + " ".join(args.prefix),
    ]
    return header, [uniq[k] for k in sorted(uniq)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("ardupilot")
    a.add_argument("--tree", required=True)
    a.add_argument("--commit", required=True)
    a.add_argument("--vehicle", default="ArduCopter")
    a.add_argument("--prefix", action="append")
    a.add_argument("--out", required=True)
    p = sub.add_parser("px4")
    p.add_argument("--root", required=True)
    p.add_argument("--commits", required=True, help="which commit(s) the files come from")
    p.add_argument("--prefix", action="append")
    p.add_argument("--out", required=True)
    args = ap.parse_args()
    if args.cmd == "ardupilot":
        args.prefix = args.prefix or ARDUPILOT_PREFIXES
        header, rows = extract_ardupilot(args)
    else:
        args.prefix = args.prefix or PX4_PREFIXES
        header, rows = extract_px4(args)
    header.append("# name\ttype\tmin\tmax\tvalues\tbitmask")
    with open(args.out, "w") as f:
        f.write("\n".join(header + rows) + "\n")
    unknown = sum(1 for r in rows if r.split("\t")[1] == "unknown")
    print(f"{args.out}: {len(rows)} parameters ({unknown} of unknown type)", file=sys.stderr)


if __name__ == "__main__":
    main()
