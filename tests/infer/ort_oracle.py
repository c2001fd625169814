"""Python onnxruntime as the oracle for the Rust ort path (crates/infer/tests/oracle.rs).

usage: ort_oracle.py MODEL.onnx SPEC.json OUT_PREFIX
SPEC: {"inputs": [{"name", "shape", "file"}]} with float32 little-endian input files.
Writes OUT_PREFIX.<output name>.f32 for every output, in the model's output order.
"""
import json
import sys

import numpy as np
import onnxruntime as ort


def main():
    model, spec, out = sys.argv[1:4]
    spec = json.load(open(spec))
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    s = ort.InferenceSession(model, opts, providers=["CPUExecutionProvider"])
    feeds = {i["name"]: np.fromfile(i["file"], "<f4").reshape(i["shape"]) for i in spec["inputs"]}
    for o, v in zip(s.get_outputs(), s.run(None, feeds)):
        np.ascontiguousarray(v, dtype="<f4").tofile(f"{out}.{o.name}.f32")


if __name__ == "__main__":
    main()
