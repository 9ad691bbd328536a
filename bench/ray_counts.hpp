// The work kdrt's traversal does per ray, counted by a second copy of the implementation built
// with KDRT_TRAVERSAL_STATS (ray_counts.cpp, all static), so the copy the program times is the
// plain one.
#pragma once

#include "kdrt.h"

#include <string>
#include <vector>

namespace kb {

// Builds the tree kdrt_tree_build(mesh, options) builds (the build is deterministic) with the
// counting copy and adds up the work of kdrt_intersect on every ray into total.
bool count_traversal(const kdrt_triangles &mesh, const kdrt_build_options &options,
                     const std::vector<kdrt_ray> &rays, kdrt_traversal_stats &total, std::string &error);
// The same for the rays as one batch: kdrt_intersect_batch, or kdrt_occluded_batch (any_hit).
bool count_batch(const kdrt_triangles &mesh, const kdrt_build_options &options, const std::vector<kdrt_ray> &rays,
                 bool any_hit, kdrt_traversal_stats &total, std::string &error);

}  // namespace kb
