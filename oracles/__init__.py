"""Independent references that the tests, the benchmarks and the research scripts compare ``lagrange`` against:
hand-written closed forms (:mod:`oracles.closed_form`) and the literal Euler-Lagrange derivation
(:mod:`oracles.euler_lagrange`). Imported from the repository root; not part of the installed package."""
