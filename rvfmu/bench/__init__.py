"""Bench data: measured TE records (`measured`), the model against them (`compare`),
calibration to measurements and catalogue figures (`calibration`) and the presets
against their frames' catalogue (`catalogue`)."""
