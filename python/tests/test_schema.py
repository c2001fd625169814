"""schema/policy.json's Python side: every name a mode or a dataset reads is a declared feature,
every command has a unit, and the one manifest writer hashes the file it describes."""
import json
import math
import os

import pytest

from unitac_tools import schema


def test_every_feature_a_mode_reads_is_declared():
    keys = {f["key"] for f in schema.SCHEMA["features"]}
    assert set(schema.LEARNED_FEATURES) == set(schema.MODES)
    for mode, feats in schema.LEARNED_FEATURES.items():
        assert feats, mode
        assert set(feats) <= keys, (mode, set(feats) - keys)
    # A demonstration dataset records every feature some mode's policy reads, and only those.
    recorded = [k for _, k in schema.DATASET_FEATURES]
    assert len(recorded) == len(set(recorded))
    assert set(recorded) == {k for feats in schema.LEARNED_FEATURES.values() for k in feats}


def test_every_command_has_a_unit_and_the_readout_range_is_ordered():
    assert schema.COMMANDS
    for c in schema.COMMANDS:
        assert schema.UNITS[c], c
    assert 0.0 < schema.K_MIN < schema.PRIOR_K < schema.K_MAX
    assert 0.0 < schema.FAR_FRACTION < 1.0


def test_the_manifest_names_the_file_it_describes(tmp_path):
    (tmp_path / schema.ONNX_FILE).write_bytes(b"not a model, only bytes to hash")
    inputs = [{"name": schema.STIFFNESS_INPUT, "shape": ["batch", 2],
               "normalization": {"mode": "mean_std", "mean": [0.0, 1.0], "std": [1.0, 2.0]}}]
    m = schema.write_policy_manifest(str(tmp_path), "p", "test", 30, inputs,
                                     schema.stiffness_actions(), {"mode": "identity"})
    on_disk = json.loads((tmp_path / "manifest.json").read_text())
    assert on_disk == m
    assert m["sha256"] == schema.sha256(os.path.join(tmp_path, schema.ONNX_FILE))
    assert m["output"]["shape"] == ["batch", 1, 1]
    assert m["inputs"][0]["dtype"] == schema.DTYPE
    assert m["output"]["actions"][0]["min"] == schema.K_MIN


def test_a_nan_never_reaches_a_manifest(tmp_path):
    (tmp_path / schema.ONNX_FILE).write_bytes(b"x")
    inputs = [{"name": "a", "shape": ["batch", 1],
               "normalization": {"mode": "mean_std", "mean": [math.nan], "std": [1.0]}}]
    with pytest.raises(ValueError):
        schema.write_policy_manifest(str(tmp_path), "p", "test", 30, inputs,
                                     schema.stiffness_actions(), {"mode": "identity"})
