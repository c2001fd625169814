"""The UniTac robot stack's Python tools, each run as `python -m unitac_tools.<module>`:

- schema: schema/policy.json's Python side and the one writer of a policy bundle's manifest.json
- generate_reference: the reference model bundle (encoder, property head, velocity models)
- train_projector: the touch projector (rectified flow) and the cup stiffness readout
- fit_reference_policy: the reference policy's latent -> stiffness readout
- lerobot_dataset: demonstrations laid out as a LeRobot v3.0 dataset
- train_policy: the learned VLA / VTLA-real / VTLA-pred policies

Their tests: `pytest python/tests` (scripts/test runs them).
"""
