"""Studies of qpbench's own solver, pi-robust, built on the neutral harness of
``qpbench.bench``: the head-to-head against the fastest external pairs (``head_to_head``), the
sequence mode with its warm-start target (``sequence``), where its time goes (``breakdown``,
against the compiled floor of ``compiled_floor``), pi-robust against one sparse factorization
(``speed``, the factorization timed by ``factorization``, which the dense-pile study of
``qpbench scaling`` uses too), and the report's section on its targets (``targets``).

The harness never imports this package: the report takes these sections from its caller.
"""
