// A boundary as the physics reads it: its object, contact, extents, active window, friction and motion in SI units
// (boundaries[] of the scene file, after defaults, validation and scaling: scene/scene_parse.cpp; facility objects
// stand for generic pieces that scene/facilities.h expand_boundary builds). physics/boundary.cuh turns it into the
// kernels' parameters and reads nothing else of the scene (docs/developer_guide.md "Layers").
#pragma once

#include <array>
#include <limits>
#include <string>
#include <vector>

namespace fbar {

enum class BoundaryObject {
  Walls, Box, Sphere, Cylinder, Plane, Floor, Bathymetry, Velocity, Piston, Pump,
  HalfSpace,  ///< not a scene object: a piece of a facility object (scene/facilities.h expand_boundary)
  OSU_LWF_RAMP, OSU_LWF_PADDLE, OSU_TWB_RAMP, OSU_TWB_PADDLE, USGS_RAMP, USGS_GATE, WASIRF_PUMP, TOKYO_HARBOR
};
enum class Contact { Sticky, Slip, Separable };

struct BoundarySpec {
  BoundaryObject object = BoundaryObject::Walls;
  Contact contact = Contact::Sticky;
  std::array<double, 3> domain_start{0.0, 0.0, 0.0};    ///< [m]
  std::array<double, 3> domain_end{0.0, 0.0, 0.0};      ///< [m]
  std::array<double, 2> time{0.0, std::numeric_limits<double>::infinity()};  ///< [s] active window
  double friction_static = 0.0;
  double friction_dynamic = 0.0;
  std::array<double, 3> velocity{0.0, 0.0, 0.0};        ///< [m/s]
  /// [rad/s] fbar's: the boundary turns at this angular velocity about rotation_center (which moves with it), from
  /// time[0]; 0: it does not turn
  std::array<double, 3> angular_velocity{0.0, 0.0, 0.0};
  std::array<double, 3> rotation_center{0.0, 0.0, 0.0};  ///< [m] at time[0] (the parser's default: the box's centre)
  std::string file;
  double output_frequency = 0.0;        ///< [Hz]
  std::array<int, 3> array{1, 1, 1};
  std::array<double, 3> spacing{0.0, 0.0, 0.0};
  std::vector<std::array<double, 2>> bathymetry;
  bool use_custom_bathymetry = false;
};

}  // namespace fbar
