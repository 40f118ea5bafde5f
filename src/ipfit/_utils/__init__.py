"""Private utilities every layer may use: argument checks (:mod:`~ipfit._utils.validation`, the one
message template), small numeric kernels (:mod:`~ipfit._utils.numeric`), atomic file output
(:mod:`~ipfit._utils.atomic`), optional packages (:mod:`~ipfit._utils.optional`), worker-thread counts
(:mod:`~ipfit._utils.threads`) and the fields every in-memory result shares
(:mod:`~ipfit._utils.result`).

Nothing is re-exported here: the command line imports :mod:`~ipfit._utils.atomic` before numpy
loads, and importing this package must not load the others.
"""
