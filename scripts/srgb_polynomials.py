#!/usr/bin/python3
"""The sRGB curves' polynomials of the accumulate kernel (nn/kernel_filter_kernels.cpp).

x^p for x in (0, 1] is split as 2^(p e) * m^p with x = 2^e m, m in [1, 2): 2^(p e) comes from a table of
the 16 exponents e = 0 .. -15, m^p from a polynomial in t = 2 m - 3 (t in [-1, 1)), the Chebyshev
interpolant of the given degree converted to powers of t. Prints the coefficients (highest power first,
as Horner's rule takes them), the table and the worst relative error on a fine grid of m.

Run with /usr/bin/python3 (numpy).
"""
import numpy as np
from numpy.polynomial import chebyshev as C

for name, p, degree in (("decode", 2.4, 7), ("encode", 1 / 2.4, 7)):
    m = np.linspace(1.0, 2.0, 400001)
    t = 2 * m - 3
    coeff = C.cheb2poly(C.chebinterpolate(lambda u: ((u + 3) / 2) ** p, degree))
    approx = np.polyval(coeff[::-1], t)
    err = np.max(np.abs(approx / m ** p - 1))
    print(f"// {name}: m^{p:.10g}, degree {degree}, worst relative error {err:.2e}")
    print("{" + ", ".join(f"{c:.9e}f" for c in coeff[::-1]) + "}")
    print("{" + ", ".join(f"{2.0 ** (p * -e):.9e}f" for e in range(16)) + "}")
