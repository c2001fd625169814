"""Small ONNX fixtures for the inference tests: a velocity model that returns NaN.

usage: make_fixtures.py OUT_DIR
"""
import os
import sys

import onnx
from onnx import TensorProto, helper

D = 64


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    # v = x * 0 / (t - t): NaN everywhere (0/0), like a model whose weights went bad.
    nodes = [
        helper.make_node("Sub", ["t", "t"], ["zero"]),
        helper.make_node("Mul", ["x", "zero"], ["x0"]),
        helper.make_node("Div", ["x0", "zero"], ["nan"]),
        helper.make_node("Identity", ["nan"], ["v"]),
    ]
    g = helper.make_graph(
        nodes, "velocity_nan",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", D]),
         helper.make_tensor_value_info("t", TensorProto.FLOAT, ["batch", 1]),
         helper.make_tensor_value_info("cond", TensorProto.FLOAT, ["batch", D + 1])],
        [helper.make_tensor_value_info("v", TensorProto.FLOAT, ["batch", D])])
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 20)])
    m.ir_version = 9
    onnx.checker.check_model(m)
    onnx.save(m, os.path.join(out, "velocity_nan.onnx"))


if __name__ == "__main__":
    main()
