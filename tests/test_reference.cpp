// Every query on generated scenes against the brute-force double-precision reference, for every
// leaf size (see kt::check_scene): kt::reference_ray_count() random rays per scene, half starting
// inside the scene's box and half outside it.
#include "test_support.hpp"

#include <catch2/catch.hpp>

TEST_CASE("random triangle soups agree with the reference", "[reference]") {
    SECTION("sparse") { kt::check_scene(kt::random_soup(500, 1), kt::reference_ray_count(), 101); }
    SECTION("dense, with many overlapping triangles") { kt::check_scene(kt::random_soup(4000, 2), kt::reference_ray_count(), 102); }
}

TEST_CASE("height field grids agree with the reference", "[reference]") {
    // Integer heights: many coplanar neighbours and shared edges, axis-aligned triangle boxes.
    SECTION("square") { kt::check_scene(kt::grid(40, 40, 3), kt::reference_ray_count(), 103); }
    SECTION("long and thin") { kt::check_scene(kt::grid(200, 8, 4), kt::reference_ray_count(), 104); }
}

TEST_CASE("spheres agree with the reference", "[reference]") {
    SECTION("coarse") { kt::check_scene(kt::sphere(30, 60, 1.0), kt::reference_ray_count(), 105); }
    SECTION("coarse, as a triangle soup") { kt::check_scene(kt::as_soup(kt::sphere(30, 60, 1.0)), kt::reference_ray_count(), 106); }
    SECTION("far from the origin") {
        kt::check_scene(kt::translated(kt::sphere(30, 60, 2.0), 1000, -2000, 500), kt::reference_ray_count(), 107);
    }
    SECTION("fine: 20,000 triangles, slivers at the poles") { kt::check_scene(kt::sphere(64, 160, 1.0), kt::reference_ray_count(), 108); }
}
