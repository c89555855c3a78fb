// SPDX-License-Identifier: MIT
#include "processor/svp/seawater.hpp"

#include <algorithm>
#include <cmath>

namespace pitmap::proc::svp {

namespace {

// IPTS-68 from ITS-90 (Saunders 1990): the 1983 algorithms were fitted on IPTS-68.
double T68(double t90) {
    return 1.00024 * t90;
}

// Polynomial c[0] + c[1] x + c[2] x^2 + ... (Horner).
template <int N>
double Poly(const double (&c)[N], double x) {
    double v = 0;
    for (int i = N - 1; i >= 0; --i) v = v * x + c[i];
    return v;
}

}  // namespace

double SoundSpeedChenMillero(double salinity_psu,
                             double temperature_its90_c,
                             double pressure_dbar) {
    // UNESCO 1983, pp. 46-49: C(S,T,P) = Cw(T,P) + A(T,P) S + B(T,P) S^1.5 + D(T,P) S^2, with P in
    // bar; the coefficients are Chen & Millero (1977) as printed there.
    const double t = T68(temperature_its90_c);
    const double p = pressure_dbar / 10.0;
    const double s = std::max(salinity_psu, 0.0);
    static constexpr double c0[] = {
        1402.388, 5.03711, -5.80852e-2, 3.3420e-4, -1.47800e-6, 3.1464e-9};
    static constexpr double c1[] = {0.153563, 6.8982e-4, -8.1788e-6, 1.3621e-7, -6.1185e-10};
    static constexpr double c2[] = {3.1260e-5, -1.7107e-6, 2.5974e-8, -2.5335e-10, 1.0405e-12};
    static constexpr double c3[] = {-9.7729e-9, 3.8504e-10, -2.3643e-12};
    static constexpr double a0[] = {1.389, -1.262e-2, 7.164e-5, 2.006e-6, -3.21e-8};
    static constexpr double a1[] = {9.4742e-5, -1.2580e-5, -6.4885e-8, 1.0507e-8, -2.0122e-10};
    static constexpr double a2[] = {-3.9064e-7, 9.1041e-9, -1.6002e-10, 7.988e-12};
    static constexpr double a3[] = {1.100e-10, 6.649e-12, -3.389e-13};
    static constexpr double b0[] = {-1.922e-2, -4.42e-5};
    static constexpr double b1[] = {7.3637e-5, 1.7945e-7};
    const double cw = Poly(c0, t) + (Poly(c1, t) + (Poly(c2, t) + Poly(c3, t) * p) * p) * p;
    const double a = Poly(a0, t) + (Poly(a1, t) + (Poly(a2, t) + Poly(a3, t) * p) * p) * p;
    const double b = Poly(b0, t) + Poly(b1, t) * p;
    const double d = 1.727e-3 - 7.9836e-6 * p;
    return cw + a * s + b * s * std::sqrt(s) + d * s * s;
}

double DepthFromPressureUnesco(double pressure_dbar, double latitude_deg) {
    // UNESCO 1983, p. 28: depth = (((-1.82e-15 P + 2.279e-10) P - 2.2512e-5) P + 9.72659) P / g,
    // g = 9.780318 (1 + (5.2788e-3 + 2.36e-5 x) x) + 1.092e-6 P, x = sin^2(latitude).
    const double sn = std::sin(latitude_deg * M_PI / 180.0);
    const double x = sn * sn;
    const double p = pressure_dbar;
    const double g = 9.780318 * (1.0 + (5.2788e-3 + 2.36e-5 * x) * x) + 1.092e-6 * p;
    return (((-1.82e-15 * p + 2.279e-10) * p - 2.2512e-5) * p + 9.72659) * p / g;
}

double SalinityFromConductivity(double conductivity_mS_cm,
                                double temperature_its90_c,
                                double pressure_dbar) {
    if (!(conductivity_mS_cm > 0.0)) return 0.0;
    // UNESCO 1983, pp. 6-12 (PSS-78): R = C / C(35,15,0) = Rp rt Rt, S from Rt.
    const double t = T68(temperature_its90_c);
    const double p = pressure_dbar;
    const double r = conductivity_mS_cm / kStandardConductivity_mS_cm;
    static constexpr double c[] = {0.6766097, 2.00564e-2, 1.104259e-4, -6.9698e-7, 1.0031e-9};
    static constexpr double e[] = {0.0, 2.070e-5, -6.370e-10, 3.989e-15};
    static constexpr double a[] = {0.0080, -0.1692, 25.3851, 14.0941, -7.0261, 2.7081};
    static constexpr double b[] = {0.0005, -0.0056, -0.0066, -0.0375, 0.0636, -0.0144};
    constexpr double k = 0.0162;
    const double rt_t = Poly(c, t);
    const double rp =
        1.0 + Poly(e, p) / (1.0 + 3.426e-2 * t + 4.464e-4 * t * t + (4.215e-1 - 3.107e-3 * t) * r);
    const double rt = r / (rp * rt_t);
    if (!(rt > 0.0)) return 0.0;
    const double root = std::sqrt(rt);
    const double ft = (t - 15.0) / (1.0 + k * (t - 15.0));
    double s = Poly(a, root) + ft * Poly(b, root);
    if (s < 2.0) {
        // Hill, Dauphinee & Woods (1986): S = S78 - a0 / (1 + 1.5 x + x^2)
        //                                     - b0 f(t) / (1 + y^1/2 + y + y^3/2), x = 400 Rt, y =
        //                                     100 Rt.
        const double x = 400.0 * rt;
        const double sy = 10.0 * root;
        s -= a[0] / (1.0 + x * (1.5 + x)) + b[0] * ft / (1.0 + sy * (1.0 + sy * (1.0 + sy)));
    }
    return std::max(s, 0.0);
}

}  // namespace pitmap::proc::svp
