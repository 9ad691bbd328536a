// kdrt's implementation again, every function static and the traversal counting its work.
#define KDRT_STATIC
#define KDRT_TRAVERSAL_STATS
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include "ray_counts.hpp"

namespace kb {

namespace {

// The counting copy's tree over mesh, or nullptr with error set.
kdrt_tree *build(const kdrt_triangles &mesh, const kdrt_build_options &options, std::string &error)
{
    kdrt_tree *tree = nullptr;
    const kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, nullptr);
    if (r != KDRT_SUCCESS) error = std::string("kdrt_tree_build: ") + kdrt_result_string(r);
    return tree;
}

}  // namespace

bool count_traversal(const kdrt_triangles &mesh, const kdrt_build_options &options,
                     const std::vector<kdrt_ray> &rays, kdrt_traversal_stats &total, std::string &error)
{
    kdrt_tree *tree = build(mesh, options, error);
    if (!tree) return false;
    total = kdrt_traversal_stats();
    for (const kdrt_ray &ray : rays) {
        kdrt_hit hit;
        kdrt_intersect_counted(tree, &ray, &hit, &total);
    }
    kdrt_tree_free(tree);
    return true;
}

bool count_batch(const kdrt_triangles &mesh, const kdrt_build_options &options, const std::vector<kdrt_ray> &rays,
                 bool any_hit, kdrt_traversal_stats &total, std::string &error)
{
    kdrt_tree *tree = build(mesh, options, error);
    if (!tree) return false;
    total = kdrt_traversal_stats();
    const uint32_t n = uint32_t(rays.size());
    if (any_hit) {
        std::vector<uint8_t> occluded(rays.size());
        kdrt_occluded_batch_counted(tree, rays.data(), n, occluded.data(), &total);
    } else {
        std::vector<kdrt_hit> hits(rays.size());
        kdrt_intersect_batch_counted(tree, rays.data(), n, hits.data(), &total);
    }
    kdrt_tree_free(tree);
    return true;
}

}  // namespace kb
