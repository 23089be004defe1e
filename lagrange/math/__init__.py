"""Small mathematics the algorithms share: spatial algebra (:mod:`~lagrange.math.spatial`), a polynomial
sine and cosine (:mod:`~lagrange.math.sincos`), and trace-time scalar folding with its small symmetric solve
(:mod:`~lagrange.math.scalar`)."""
