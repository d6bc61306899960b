"""Scenes shipped with nsfem (``default.toml``: the paper's delaminated shaft)."""
