"""Symbolic half of simucal (SymPy): frames, turntable, error models, and the
derivations of dong2018 (norm observation, back-substitution, frame
unification), their remainders, and the audit of the paper's equations.

Run by ``simucal derive``, which writes ``generated/``. Nothing here is
imported on the runtime's hot path.
"""
