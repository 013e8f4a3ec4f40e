"""pi-robust compiled with numba, on envelope (skyline) Cholesky factors.

The kernel runs the whole of pi-robust (``qpbench.solvers.pi_robust``) in one compiled call
for problems of at most the accuracy table's ``compiled_limit`` contacts. Its modules, in the
order in which they build on each other:

- :mod:`.constants`: thresholds, status and path codes (no numba; the Python path imports
  the rules it shares from here);
- :mod:`.structures`: the tuples that carry a solve's arrays, and the packed options;
- :mod:`.residual`: qpbench's natural residual in scipy's summation order, its rounding
  bounds and the certificate;
- :mod:`.ordering`: reverse Cuthill-McKee, the permuted matrix, its upper triangle and the
  envelope's row widths;
- :mod:`.factor`: the envelope Cholesky factor, its substitutions, row deletions by plane
  rotations, and the cache of kept factors that a policy solve goes through;
- :mod:`.active_set`: the primal active-set method on one prox step;
- :mod:`.pivoting`: block principal pivoting on one prox step;
- :mod:`.prox`: proximal policy iteration, its drift extrapolation, polish and finish;
- :mod:`.interior`: the ordered solve: policy iteration, then the interior point;
- :mod:`.parallel`: the presolve that drops the looser of parallel contacts;
- :mod:`.entry`: the entry points ``envelope_pi_robust``, its narrow call ``pi_robust_into``
  (the presolve first), ``relaxed_pi_robust``, ``contact_block_sweeps`` and ``warm_up``.
- :mod:`.call`: the call of ``pi_robust_into`` from Python, past numba's dispatcher where the
  arrays are of the compiled types.

Importing the package itself loads nothing else (in particular not numba).
"""
