"""Constants shared by pi-robust's compiled kernel and its Python path.

This module imports neither numba nor the rest of the kernel, so that
``qpbench.solvers.pi_robust`` can import the rules both paths share
(:data:`COUPLED`, :data:`DRIFT_RATIO`) at its top level without loading the kernel.
"""

from __future__ import annotations

# The active-set method frees every violating contact at once except those coupled to one
# freed before them: ``Q_ij > COUPLED sqrt(D_i D_j)``, the cosine between the two contacts'
# rows of ``J M^-1/2`` (positive couplings on grids are about 0.35; nearly perpendicular
# contacts are below 0.02).
COUPLED = 0.1
# A settled prox step's change of l is taken for a drift along the null space of Q_FF, and
# followed to the first free contact that reaches zero, when it is at least this fraction of
# the change in the step before (a drift keeps its length, a slow contraction shrinks it).
DRIFT_RATIO = 0.999

# Floating-point freedoms of the factor and its solves: a product and the sum it enters may be
# fused into one multiply-add (every x86-64 CPU with FMA3 fuses the same pairs), but no sum is
# reordered: a reordering is the compiler's to choose by the CPU's vector width, and the answer
# would then depend on the CPU. The inner products keep LANES partial sums of their own instead
# (:func:`.factor._subtract_products`), which vectorise the same on every CPU. NaN and infinity
# keep their meaning, so that a failing pivot is still caught.
REDUCTIONS = {"contract"}
LANES = 8
# The functions that every step of policy iteration runs are compiled without numba's
# reference counting (its ``_nrt`` option), which otherwise adds an atomic increment and
# decrement for every array a function binds, slices or passes on. Such a function cannot
# allocate (numba refuses to compile it) and must not return an array (no count would own
# it; tests/test_pi_robust_kernel.py checks every one's return type).
WITHOUT_REFCOUNTS = {"_nrt": False}
# The contacts are put in reverse Cuthill-McKee order when the envelope in the posed order
# costs more than WIDE_ENVELOPE_WORK multiply-adds to factor (below that the ordering costs
# more than it saves) and either there are more than ``order_above`` contacts or the envelope
# costs more than WIDE_ENVELOPE of a dense factorization's n^3 / 6 (Anitescu's relaxation
# puts the columns n + mu t and n - mu t of one contact n apart).
WIDE_ENVELOPE = 0.5
WIDE_ENVELOPE_WORK = 1e4
# A start that the first ``start_sweeps`` sweeps leave unsolved gets more, in all as many as
# cost about SWEEP_SHARE of one factorization of its whole envelope (a sweep costs about one
# multiply-add per entry of Q), MOST_START_SWEEPS at most: on wide grids a factorization costs
# a hundred sweeps, and the sweeps put more contacts on the right side of the active set.
SWEEP_SHARE = 0.4
MOST_START_SWEEPS = 50
# A block factored with at least DEPENDENT_CONTACTS dependent contacts (pivots
# L_ii^2 < DEPENDENT_PIVOT rho D_i: contact i nearly a combination of the free contacts before
# it) is nearly singular at this rho, and block pivoting's iterate on it swings (see
# ``pivoting._inner_lcp``).
DEPENDENT_PIVOT = 100.0
DEPENDENT_CONTACTS = 4
# The active-set method's steps that only fix contacts, at most UPDATE_FIXED of them, delete
# their rows from the factor solved last instead of refactoring
# (``factor._block_solve_fixing``), on problems whose D_i > 0 span at most UPDATE_SPREAD
# (wider spreads make the updated factor round differently enough to change the pivots).
UPDATE_FIXED = 4
UPDATE_SPREAD = 1e6
# Problems of at most DENSE_CONTACTS contacts that the start sweeps leave unsolved are first
# tried by block principal pivoting on a dense copy of Q (:mod:`.dense`), at most
# DENSE_BUDGET block solves, before the general path's set-up: it touches less of the kernel.
# Its factor holds a contact at zero when its pivot L_ii^2 falls below DENSE_DEPENDENT_PIVOT
# D_i (dependent on the free contacts before it), and a contact at zero whose w_i falls short
# of zero by at most DENSE_SLACK tol scale (rounding, on dependent contacts) counts as
# feasible: it adds at most that share of the tolerance to the residual.
DENSE_CONTACTS = 32
DENSE_BUDGET = 8
DENSE_DEPENDENT_PIVOT = 1e-10
DENSE_SLACK = 0.1
# Status codes of a prox run.
PROX_CONVERGED, PROX_BUDGET, PROX_STALLED = 0, 1, 2
# Paths of a whole solve, and their names in a solver's ``info["path"]``.
PATH_START, PATH_POLICY_ITERATION, PATH_INTERIOR, PATH_NONE, PATH_DECLINED, PATH_SWEEPS, \
    PATH_DENSE = 0, 1, 2, 3, 4, 5, 6
SOLVE_PATHS = ("start", "policy iteration", "interior point + policy iteration",
               "interior point did not converge", "declined: envelope too wide",
               "start sweeps", "dense pivoting")
# A path of the problem without its looser parallel contacts (:mod:`.parallel`) is reported
# as that path plus PATH_PARALLEL_DROPPED.
PATH_PARALLEL_DROPPED = len(SOLVE_PATHS)
PATH_NAMES = SOLVE_PATHS + tuple(f"{name}, looser parallel contacts dropped"
                                 for name in SOLVE_PATHS)
# Contacts i and j count as parallel when Q_ij^2 >= (1 - PARALLEL_DEFECT) Q_ii Q_jj: columns
# of G at an angle of about sqrt(PARALLEL_DEFECT) rad or less, about where rounding leaves
# the Cauchy-Schwarz defect of two equal columns (1e-16 relative per product).
PARALLEL_DEFECT = 1e-14
