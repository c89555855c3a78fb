// SPDX-License-Identifier: MIT
// Frame and attitude conventions, written down once for the whole project.
//
// Frames (names used in variables as T_<to>_<from>, points as points_<frame>):
//   world   local East-North-Up tangent frame at the survey origin (GeographicLib
//           LocalCartesian); metres; z up. All maps, meshes and SLAM poses live here.
//   ned     local North-East-Down frame at the vehicle (navigation frame of the attitude).
//   vehicle vehicle body, FRD: x forward, y starboard, z down; origin at the INS reference
//           point. Lever arms are vehicle-frame vectors.
//   span    NovAtel SPAN vehicle frame, RFU: x right, y forward, z up (IMU logs use it).
//   sonar   multibeam sonar head: x forward, y starboard, z down, origin at the transducer;
//           a beam at angle theta (positive to starboard) with range r lies at
//           (0, r sin theta, r cos theta) before profile tilt.
//
// Attitude: roll, pitch, yaw (radians in code, degrees only at I/O) are the z-y-x Tait-Bryan
// angles of the vehicle (FRD) frame relative to NED: R_ned_vehicle = Rz(yaw) Ry(pitch) Rx(roll).
// Roll > 0: starboard side down. Pitch > 0: bow up. Yaw: clockwise from true north.
// NovAtel SPAN's roll (right-handed about y forward), pitch (right-handed about x right) and
// azimuth (clockwise from north), applied in the order azimuth, pitch, roll, are exactly these
// angles, so INS attitudes are used as they come (degrees -> radians).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace pitmap::frames {

inline constexpr const char* kWorld = "world";
inline constexpr const char* kNed = "ned";
inline constexpr const char* kVehicle = "vehicle";
inline constexpr const char* kSpan = "span";
inline constexpr const char* kSonar = "sonar";

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double DegToRad(double deg) {
    return deg * (kPi / 180.0);
}
inline constexpr double RadToDeg(double rad) {
    return rad * (180.0 / kPi);
}

// R_enu_ned: maps NED vectors to ENU (a symmetric permutation with a sign flip).
inline Eigen::Matrix3d RotationEnuFromNed() {
    Eigen::Matrix3d r;
    r << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    return r;
}

// R_vehicle_span: maps SPAN RFU vectors to the FRD vehicle frame.
inline Eigen::Matrix3d RotationVehicleFromSpan() {
    Eigen::Matrix3d r;
    r << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    return r;
}

// R_ned_vehicle = Rz(yaw) Ry(pitch) Rx(roll); angles in radians.
Eigen::Matrix3d RotationNedFromRpy(double roll, double pitch, double yaw);
// R_world_vehicle for world = ENU: R_enu_ned * R_ned_vehicle.
Eigen::Matrix3d RotationWorldFromRpy(double roll, double pitch, double yaw);

struct Rpy {
    double roll = 0;   // radians
    double pitch = 0;  // radians, in [-pi/2, pi/2]
    double yaw = 0;    // radians, in (-pi, pi]
};
// Inverse of RotationNedFromRpy. At pitch = +-pi/2 (gimbal lock) roll is set to 0 and the
// whole rotation about the vertical is put in yaw.
Rpy RpyFromRotationNed(const Eigen::Matrix3d& R_ned_vehicle);
// Inverse of RotationWorldFromRpy.
Rpy RpyFromRotationWorld(const Eigen::Matrix3d& R_world_vehicle);

// Wraps an angle to (-pi, pi].
double WrapPi(double angle_rad);

}  // namespace pitmap::frames
