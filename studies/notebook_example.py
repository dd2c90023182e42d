# %% [markdown]
# # A tolerance study in pandas: what an engineer does after `rvte mc` and `rvte sobol`
#
# The question: which tolerance decides the TE of the reducers we build, and how
# does te_pp grow with it?  The Sobol ranking names the factor; the Monte Carlo
# reducers, grouped by that factor's decile, show how much te_pp it costs.
#
# Plain Python in notebook cells (`# %%`): run it whole, or cell by cell in
# Jupyter or VS Code.
#
#     rvte mc    studies/rv40e_121_sobol.toml      # 1000 reducers
#     rvte sobol studies/rv40e_121_sobol.toml      # N = 1024: 10 240 TE curves
#     python studies/notebook_example.py           # reuses both, computes nothing
#
# Another study: `python studies/notebook_example.py STUDY.toml [OUTPUT_DIR]`, or
# the environment variables RVTE_STUDY and RVTE_OUTPUT (for a notebook).  The
# figure goes to the study's output folder (notebook_te_pp_by_decile.png).

# %% Which study
import os
import sys
from pathlib import Path

import matplotlib

if "ipykernel" not in sys.modules and not os.environ.get("DISPLAY"):
    matplotlib.use("Agg")  # a script without a display: figures go to files only
import matplotlib.pyplot as plt
import pandas as pd

import tolerance
from tolerance.frames import factor_column

HERE = Path(__file__).resolve().parent if "__file__" in globals() else Path("studies").resolve()
ARGS = [a for a in sys.argv[1:] if not a.startswith("-")] if "ipykernel" not in sys.modules else []
STUDY = Path(ARGS[0] if ARGS else os.environ.get("RVTE_STUDY", HERE / "rv40e_121_sobol.toml"))
OUTPUT = ARGS[1] if len(ARGS) > 1 else os.environ.get("RVTE_OUTPUT")  # None: the study's own
DECILES = 10

# %% Run the study, or reuse what `rvte mc` / `rvte sobol` stored (every batch is reused)
# In-process: with worker processes (processes=2) the cells below must sit under
# `if __name__ == "__main__":`.
mc = tolerance.run_mc(STUDY, output=OUTPUT, plots=False)
sobol = tolerance.run_sobol(STUDY, output=OUTPUT, plots=False)
study, folder = mc.study, Path(mc.study.output)
print(f"study {study.name!r}: {mc.n} reducers, Sobol N = {sobol.n}, results in {folder}")

# %% The reducers: one row each, as the output folder stores them
reducers = tolerance.load_results(folder).iloc[: mc.n]  # equal to mc.to_df()
metric = "te_pp_arcsec" if "te_pp_arcsec" in reducers else study.metric_columns[0]
print(
    reducers.select_dtypes("float")
    .describe()
    .T[["mean", "std", "min", "50%", "max"]]
    .to_string(float_format="{:.3g}".format)
)
if "passed" in reducers:
    print(
        f"yield {reducers['passed'].mean():.4f} ({int(reducers['passed'].sum())} of "
        f"{int(reducers['passed'].count())} reducers meet every spec line)"
    )

# %% The Sobol table, sorted by ST
indices = sobol.to_df()
ranked = indices.sort_values(["metric", "ST"], ascending=[True, False])
print(
    ranked[["metric", "factor", "S1", "S1_conf", "ST", "ST_conf", "notes"]].to_string(
        index=False, float_format="{:.3f}".format
    )
)

# %% The factor on top of the te_pp ranking, and te_pp by its decile
top_group = ranked[ranked["metric"] == metric].iloc[0]["factor"]
factor = next(f for f in study.factors if f.group == top_group)  # its first factor
column = factor_column(factor)
decile = pd.qcut(reducers[column], DECILES, labels=False, duplicates="drop") + 1
by_decile = reducers.groupby(decile)[metric].agg(["count", "mean", "max"])
by_decile.insert(0, f"{column} (mean)", reducers.groupby(decile)[column].mean())
by_decile.index.name = f"decile of {column}"
print(by_decile.to_string(float_format="{:.3f}".format))

# %% The figure: te_pp against the factor, the deciles' mean and maximum
fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
ax.scatter(reducers[column], reducers[metric], s=6, alpha=0.4, color="C0", label="reducers")
ax.plot(by_decile.iloc[:, 0], by_decile["mean"], "o-", color="C1", label="decile mean")
ax.plot(by_decile.iloc[:, 0], by_decile["max"], "s--", color="C3", label="decile maximum")
limit = next((s.limit for s in study.spec if s.column == metric), None)
if limit is not None:
    ax.axhline(limit, color="k", ls=":", lw=1, label=f"spec {limit:g}")
ax.set_xlabel(f"{column} (drawn value)")
ax.set_ylabel(metric)
ax.set_title(f"{study.name}: {metric} by decile of {factor.name} (top of the ST ranking)", fontsize=9)
ax.legend(fontsize=8)
ax.grid(alpha=0.3)
figure = folder / "notebook_te_pp_by_decile.png"
fig.savefig(figure, dpi=120)
print(f"wrote figure {figure}")
