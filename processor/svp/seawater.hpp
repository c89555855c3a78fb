// SPDX-License-Identifier: MIT
// Sound speed, depth and salinity of sea and fresh water from a CTD's readings (EOS-80, the
// algorithms of UNESCO Technical Papers in Marine Science 44, Fofonoff & Millard 1983). Pure.
//
// Why these and not TEOS-10 or a simpler fit: pitmap's casts come from flooded pits, i.e. fresh
// or brackish water. Chen & Millero (1977) holds for salinity 0..40, temperature 0..40 degC
// and pressure 0..1000 bar, fresh water included; Mackenzie (1981, S 25..40) and Del Grosso
// (1974, S 29..43) do not cover fresh water. TEOS-10 would need its 48-term Gibbs function
// and Absolute Salinity for a difference far below what a pit's ray tracing sees (the
// UNESCO and TEOS-10 speeds differ by < 0.1 m/s in this range).
//
// Units: temperature in degC on ITS-90 (converted inside to IPTS-68, T68 = 1.00024 T90, as
// the 1983 algorithms expect), pressure in dbar (sea pressure: 0 at the surface), salinity
// on the Practical Salinity Scale (PSS-78, no unit), conductivity in mS/cm, latitude in
// degrees. Outside the validity ranges the formulas are evaluated anyway (no error): the
// caller checks the resulting speed against the cast limits.
#pragma once

namespace pitmap::proc::svp {

// Conductivity of standard sea water C(35, 15 degC IPTS-68, 0) in mS/cm (PSS-78).
inline constexpr double kStandardConductivity_mS_cm = 42.914;

// UNESCO 1983 "SVEL": Chen & Millero (1977) sound speed in m/s.
// Check value: 1731.995 m/s at S = 40, T68 = 40 degC, P = 10000 dbar.
double SoundSpeedChenMillero(double salinity_psu, double temperature_its90_c, double pressure_dbar);

// UNESCO 1983 "DEPTH" (Saunders & Fofonoff 1976): depth in metres of sea pressure in the
// standard ocean (S = 35, T = 0 degC) with gravity varying with latitude and pressure.
// Check value: 9712.653 m at 10000 dbar, latitude 30 deg. In fresh water the true depth is
// about 2.5 % larger than this (density 1000 instead of about 1028 kg/m^3).
double DepthFromPressureUnesco(double pressure_dbar, double latitude_deg);

// UNESCO 1983 "SAL78": practical salinity from conductivity, temperature and pressure,
// extended below S = 2 by Hill et al. (1986) so that fresh water gives a small positive
// salinity rather than a negative one. Check values: S = 35 at C = 42.914 mS/cm, 15 degC, 0 dbar;
// 37.245628 at conductivity ratio 1.2, 20 degC, 2000 dbar; 27.995347 at 0.65, 5 degC,
// 1500 dbar (temperatures IPTS-68 in those tables). Conductivity <= 0 gives 0.
double SalinityFromConductivity(double conductivity_mS_cm,
                                double temperature_its90_c,
                                double pressure_dbar);

}  // namespace pitmap::proc::svp
