"""The agents: the tabular SB3 algorithms, their reference Python loop, ``learn`` on the compiled kernel, the policy,
the emotion callbacks and safe model files."""
