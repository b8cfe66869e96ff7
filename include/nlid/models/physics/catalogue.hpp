#pragma once
/// @file
/// The physics catalogue: every ready-made grey-box physics of nlid, by compile-time type.
///
/// | run-time name        | type                         | equation                                      |
/// | -------------------- | ---------------------------- | --------------------------------------------- |
/// | `throttle`           | `physics::Throttle`          | ÿ + cẏ + k(y−rest) + K·stops(y) = b u          |
/// | `mass_spring_damper` | `physics::MassSpringDamper`  | ÿ + cẏ + k(y−rest) = b u                      |
/// | `rigid_body`         | `physics::RigidBody`         | ÿ = −cẏ + b(u − u_offset)                     |
/// | `first_order`        | `physics::FirstOrder`        | τẏ = −(y − offset) + gain·u                   |
/// | `two_tank`           | `physics::TwoTank`           | ḣ₁ = bu − a₁√h₁, ḣ₂ = a₁√h₁ − a₂√h₂, y = h₂    |
///
/// Use a type directly (`GreyBox<physics::Throttle>`, fastest, no allocation per sample) or pick
/// one by name at run time with `make_physics("throttle")` (models/greybox_dynamic.hpp).

#include "nlid/models/physics/first_order.hpp"
#include "nlid/models/physics/mass_spring_damper.hpp"
#include "nlid/models/physics/rigid_body.hpp"
#include "nlid/models/physics/throttle.hpp"
#include "nlid/models/physics/two_tank.hpp"
