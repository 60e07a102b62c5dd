#pragma once
// Drops that touch coalesce. Two water drops whose footprints overlap on the glass do not stay
// two caps: surface tension pulls them into one drop within milliseconds. With `allow_overlap`
// alone the renderer keeps the union of the caps as one body of water (scene_config.h), the
// limit where the contact lines stay pinned where they were; `coalesce` takes the other limit,
// a drop that has relaxed into one smooth cap:
//   - the water is conserved: the merged drop holds the sum of the drops' volumes (drop_volume);
//   - it sits at their centre of mass on the glass (centres weighted by volume);
//   - its contact angle, gravity stretch and flattening are the volume-weighted means;
//   - its footprint radius is the one a cap of that angle, stretch and flattening needs to hold
//     that water.
// A merged drop is larger than either, so it may reach a third drop; merging repeats until no
// two footprints overlap. Overlap is judged on each footprint's enclosing circle, a times its
// gravity stretch (exact for round drops). Real merged drops often stay elongated where the old
// contact lines remain pinned; the truth lies between the two limits.
#include <vector>

#include "raindrop/render/drop.h"

namespace raindrop {

// One drop with the water of `a` and `b`, as the rules above say (outlines are not merged:
// coalescence runs before outlines are drawn, and the merged drop is round).
DropShape merge_drops(const DropShape& a, const DropShape& b);

// Merges overlapping drops until none overlap. The first drop of each merge keeps its place in
// the vector; the others are removed, the order of the rest kept. Returns the merges made.
int coalesce_drops(std::vector<DropShape>* drops);

}  // namespace raindrop
