"""Independent references that the tests, the benchmarks and the research scripts compare ``lagrange`` against:
hand-written closed forms (:mod:`oracles.closed_form`), the literal Euler-Lagrange derivation
(:mod:`oracles.euler_lagrange`) and a Pinocchio model built from a chain's parameters (:mod:`oracles.pinocchio`).
Imported from the repository root; not part of the installed package."""
