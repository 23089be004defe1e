"""Small mathematics the algorithms share: spatial algebra (:mod:`~lagrange.math.spatial`), a polynomial
sine and cosine (:mod:`~lagrange.math.sincos`), trace-time scalar folding (:mod:`~lagrange.math.scalar`) and small
linear algebra (:mod:`~lagrange.math.linalg`)."""
