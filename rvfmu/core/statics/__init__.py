"""The quasi-static model: the equivalent model of every contact (`equivalent`), the Newton
iteration (`newton`, compiled in `newton_kernel`), the solver over many (reducer, angle)
pairs (`solver`), TE curves, windup, lost motion and rigidity (`quasistatic`), the TE
metrics (`metrics`), te_pp from fewer angles (`adaptive_angles`), the independent scipy
reference (`reference`) and the compliance budget (`budget`).

May import: `base`, `laws`, `reducer`.
"""
