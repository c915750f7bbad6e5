"""
The verdict logic: the paper's printed numbers, the claims judged on our runs (direction, size against the paper's
20-seed protocol, the tests and their Holm families) and the inference they rest on.
"""
