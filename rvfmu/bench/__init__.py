"""Bench data: measured TE records (`measured`), the model against them (`compare`),
calibration to measurements and catalogue figures (the values fitted:
`calibration_values`; the data fitted to: `calibration_data`; the problem and its
residuals: `calibration_problem`; the fit: `calibration_fit`) and the presets against
their frames' catalogue (`catalogue`)."""
