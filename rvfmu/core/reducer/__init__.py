"""The reducer and its errors: the design and its checks (`design`), the shipped presets
(`presets/`), the cycloid disc profile (`profile`), the manufacturing errors of MODEL.md
section 4 (`errors`) and the load and speed limits of the small-displacement model
(`limits`).

May import: `base`, `laws`.
"""
