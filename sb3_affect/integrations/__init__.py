"""Integrations with the SB3 ecosystem: rl-zoo3 recipes (``zoo``) and the Hugging Face Hub (``hub``)."""
