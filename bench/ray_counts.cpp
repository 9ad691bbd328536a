// kdrt's implementation again, every function static and the traversal counting its work.
#define KDRT_STATIC
#define KDRT_TRAVERSAL_STATS
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include "ray_counts.hpp"

namespace kb {

bool count_traversal(const kdrt_triangles &mesh, const kdrt_build_options &options,
                     const std::vector<kdrt_ray> &rays, kdrt_traversal_stats &total, std::string &error)
{
    kdrt_tree *tree = nullptr;
    const kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, nullptr);
    if (r != KDRT_SUCCESS) {
        error = std::string("kdrt_tree_build: ") + kdrt_result_string(r);
        return false;
    }
    total = kdrt_traversal_stats();
    for (const kdrt_ray &ray : rays) {
        kdrt_hit hit;
        kdrt_intersect_counted(tree, &ray, &hit, &total);
    }
    kdrt_tree_free(tree);
    return true;
}

}  // namespace kb
