"""Expand a xacro file with the real `xacro` package and print its kinematic tree as JSON:
{"links": [...], "joints": [{"name", "type", "parent", "child", "rpy"}]}.

usage: check_urdf.py FILE.urdf.xacro [name:=value ...]
"""
import json
import os
import sys
import xml.etree.ElementTree as ET

import xacro


def main():
    path = os.path.abspath(sys.argv[1])
    mappings = dict(a.split(":=", 1) for a in sys.argv[2:])
    cwd = os.getcwd()
    os.chdir(os.path.dirname(path))  # the example includes $(cwd)/... siblings
    try:
        doc = xacro.process_file(path, mappings=mappings)
    finally:
        os.chdir(cwd)
    root = ET.fromstring(doc.toxml())
    joints = []
    for j in root.findall("joint"):
        o = j.find("origin")
        joints.append({
            "name": j.get("name"), "type": j.get("type"),
            "parent": j.find("parent").get("link"), "child": j.find("child").get("link"),
            "rpy": [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()],
        })
    print(json.dumps({"links": [l.get("name") for l in root.findall("link")], "joints": joints}))


if __name__ == "__main__":
    main()
