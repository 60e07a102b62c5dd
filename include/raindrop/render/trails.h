#pragma once
// Trails: what a drop leaves behind when gravity has pulled it down the glass.
//
// A drop stays where it landed while the contact line's pinning holds it. The line pins
// because the water advances at a larger contact angle than it recedes; Furmidge's balance
// says the drop slides once its weight along the slope exceeds what that hysteresis holds
// across its width w:
//   rho g V sin(psi) >= gamma w Delta,   Delta = cos(receding) - cos(advancing),
// psi the glass' slope from the ground (glass.h). With the capillary length l_c^2 = gamma /
// (rho g) (0.0744 cm^2 for water at 20 C) this is V sin(psi) >= w Delta l_c^2: on upright
// glass with Delta = 0.2 a cap of 60 degrees slides from a footprint radius of about 1.7 mm.
// A sliding drop leaves water behind on the glass it crossed, a thin streak uphill of it (the
// water it left is not on the glass below, where it has not been yet). The streak is made of
// small flat caps on the line uphill from the drop's rim: joined into a film where their
// spacing is below their radii's sum, a row of beads (pearling) where it is above. The drop
// gives its trail the water the trail holds, so the water on the glass is what was drawn:
//   V(drop after) + sum V(trail caps) = V(drop as drawn),
// and its rim stays where the trail starts. Overlapping caps are traced as merged drops are
// (each its own surface; allow_overlap in scene_config.h).
#include <vector>

#include "raindrop/common/rng.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

// gamma / (rho g) for water at 20 C: 0.0728 N/m / (998 kg/m^3 x 9.81 m/s^2), in cm^2.
inline constexpr double kCapillaryLengthSquaredCm2 = 0.0744;
// A trail has at most this many caps, whatever the scene file says (time stays bounded).
inline constexpr int kMaxTrailCaps = 200;

// Water volume of a drop, cm^3: the spherical cap's, times the gravity stretch and flattening
// and the outline's <s^2> (outline.h).
double drop_volume(const DropShape& d);

// The footprint's width across the slope, cm: 2 a s_max (the outline's enclosing circle).
double drop_width(const DropShape& d);

// Furmidge's balance: whether the drop slides on glass of slope `tilt` (radians from the
// ground) with contact angle hysteresis `hysteresis`.
bool drop_slides(const DropShape& d, double tilt, double hysteresis);

// Distance from the drop's centre to its rim straight uphill, cm.
double uphill_rim_distance(const DropShape& d);

// Appends the trails of the drops that slide (drawn with `rng`: every drop's hysteresis first,
// then each trail, drop by drop in order) and
// shrinks each of those drops by the water its trail took. Trail caps name their drop in
// `trail_of`; the drops themselves keep their place in the vector.
void add_trails(std::vector<DropShape>* drops, const SceneConfig::Trails& options, double tilt, Rng& rng);

}  // namespace raindrop
