"""The paper's section-5 experiments as commands (``ant-experiment``); see docs/experiments.md."""
