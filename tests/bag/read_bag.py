"""Read a bag with the independent Python library rosbags and print every message as JSON.

  read_bag.py BAG

The unitac_msgs types are registered from the .msg files in msg/unitac_msgs (rosbags parses
them itself). One JSON line per message, in bag order:
  {"topic", "type", "log_time", "msg": {field: value, ...}}
uint8[] fields become {"len": n, "sha256": hex}; nested messages become objects. A first line
{"topics": [{"name", "type", "count", "qos": n}]} lists the connections.
"""
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROOT = Path(__file__).resolve().parents[2]


def typestore():
    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for p in sorted((ROOT / 'msg/unitac_msgs/msg').glob('*.msg')):
        types.update(get_types_from_msg(p.read_text(), f'unitac_msgs/msg/{p.stem}'))
    ts.register(types)
    return ts


def plain(v):
    if isinstance(v, np.ndarray):
        if v.dtype == np.uint8:
            return {'len': int(v.size), 'sha256': hashlib.sha256(v.tobytes()).hexdigest()}
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if hasattr(v, '__dataclass_fields__'):
        return {k: plain(getattr(v, k)) for k in v.__dataclass_fields__ if k != '__msgtype__'}
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    return v


def main():
    ts = typestore()
    with AnyReader([Path(sys.argv[1])], default_typestore=ts) as r:
        # The bag's own schemas (what r.typestore was built from) must give the same fields as
        # the reference definitions (ROS Humble store + the .msg files).
        print(json.dumps({'topics': [
            {'name': c.topic, 'type': c.msgtype, 'count': c.msgcount,
             'qos': len(getattr(c.ext, 'offered_qos_profiles', []) or []),
             'schema_matches': r.typestore.fielddefs.get(c.msgtype) == ts.fielddefs.get(c.msgtype)}
            for c in r.connections]}))
        for c, t, data in r.messages():
            m = r.deserialize(data, c.msgtype)
            print(json.dumps({'topic': c.topic, 'type': c.msgtype, 'log_time': t,
                              'msg': plain(m)}))


if __name__ == '__main__':
    main()
