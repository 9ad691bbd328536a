/* kdrt.h - v0.1.0 - kd-tree ray tracing over your own triangle buffers.
   Public domain-like (MIT-0, see LICENSE at the end).

   USAGE
     In exactly one C or C++ file, before including this header:

         #define KDRT_IMPLEMENTATION
         #include "kdrt.h"

     Everywhere else include it plainly. Define KDRT_STATIC as well to make every function static
     (private to that one file). The header needs the C standard library and libm (link
     with -lm in C: kdrt_hit_surface and the optics functions call sqrt and fma).

         kdrt_triangles mesh = {0};
         mesh.positions = vertices;          // float x, y, z per vertex
         mesh.position_stride = 0;           // bytes between vertices, 0 = packed (12)
         mesh.vertex_count = vertex_count;
         mesh.indices = indices;             // 3 per triangle, or NULL for a triangle soup
         mesh.triangle_count = triangle_count;

         kdrt_build_options options = kdrt_default_build_options();
         kdrt_tree *tree = NULL;
         kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, NULL);
         if (r != KDRT_SUCCESS) { fprintf(stderr, "kdrt: %s\n", kdrt_result_string(r)); ... }

         kdrt_ray ray = {{ox, oy, oz}, 0.0f, {dx, dy, dz}, INFINITY, 0};  // 0: start at the root
         kdrt_hit hit;
         if (kdrt_intersect(tree, &ray, &hit)) { ... hit.t, hit.u, hit.v, hit.triangle ... }
         if (kdrt_occluded(tree, &ray)) { ... }

         kdrt_tree_free(tree);

   CONFIGURATION
     Every macro a user may define; all are optional. Names beginning KDRT__ are internal.
     In the one file with the implementation, before including the header:
       KDRT_IMPLEMENTATION       compile the implementation into this file
       KDRT_STATIC               every function static (the implementation is then private to it)
       KDRT_ASSERT(x)            internal invariant checks; default: assert() from <assert.h>
       KDRT_MALLOC(size, user)   default allocator when options.allocator is all zero;
       KDRT_FREE(ptr, user)      define both or neither (default: malloc and free)
       KDRT_TRAVERSAL_STATS      also compile kdrt_intersect_counted() and the batches'
                                 _counted forms, which count a query's work (nodes, leaves,
                                 triangle tests, packets); the other queries are unchanged.
                                 Define it too where they are called.
       KDRT_SAH_BINS             bins per axis of the SAH builder's binned sweep: 2 to 1024,
                                 default 256
       KDRT_SAH_EXACT_MAX        SAH nodes of at most this many triangle references are split
                                 by the exact sweep, larger ones by the binned one: 0 to
                                 4294967295, default 128 (KDRT_BUILD_QUALITY_MEDIUM's
                                 threshold)
       KDRT_SAH_REFERENCE_BUDGET the most triangle references a SAH tree holds per triangle
                                 (THE TREE): 1 to 64, default 8
     These three exist to measure the choice: the defaults are the measured best, and any value
     in range builds a valid tree, if not the same one. A value out of range stops the
     compilation with an #error.
       KDRT_NO_SIMD              leave the SIMD kernels (AVX2, AVX-512, NEON, SIMD128) and SSE2
                                 binning out: every tree runs the scalar kernel and is binned
                                 by scalar code (KERNELS)
       KDRT_NO_AVX2              leave the AVX2 and AVX-512 code out (x86-64): every tree runs
                                 the scalar kernel and is built with SSE2 alone, as on a CPU
                                 without AVX2; for compilers without target attributes
       KDRT_HEADER_FILENAME      the name this header is included by, in quotes (default
                                 "kdrt.h"): the implementation includes itself once more for
                                 each packet width (KERNELS); set it when the file is renamed
     The file with the implementation must be compiled with IEEE arithmetic: -ffast-math,
     -ffinite-math-only and MSVC's /fp:fast stop it with an #error (the other files may use
     them), and so does i386's x87 arithmetic (use -msse2 -mfpmath=sse). Contraction into FMAs
     is turned off inside the implementation whatever the command line says (PLATFORMS), except
     that Clang ignores that under an explicit -ffp-contract=fast. Flags that change rounding
     without a macro to tell (-fassociative-math alone, say) break the answers' bits silently:
     leave them off that file too.
     In every file, the same everywhere:
       KDRT_API                  the functions' linkage (default: extern, or static under
                                 KDRT_STATIC), e.g. a DLL export attribute
       KDRT_MEDIA_STACK_CAPACITY media a kdrt_media_stack holds: at least 1, default 16; it sizes
                                 the struct
     Fixed, not for defining: KDRT_MAX_DEPTH (64, the deepest tree; options.max_depth is the
     knob), KDRT_MAX_TRIANGLES and KDRT_INVALID_ID.

   OWNERSHIP
     The tree borrows the caller's buffers: kdrt_triangles.positions and .indices must stay alive
     and unchanged from kdrt_tree_build() until kdrt_tree_free(). The tree owns its nodes, its
     leaves' triangle references and a copy of the triangles laid out for the intersection tests
     (THE TREE), which kdrt_intersect() and kdrt_occluded() read; kdrt_hit_surface() and
     kdrt_spawn_ray() read the caller's buffers. Moving or editing the vertices requires a new
     build. The kdrt_triangles struct itself may be discarded after the build. Everything the
     tree owns comes from options.allocator (or KDRT_MALLOC) and goes back to it in
     kdrt_tree_free(); a kdrt_media_stack is plain data the caller owns. A loaded tree
     (kdrt_tree_load(), SAVED TREES) borrows the mesh buffers as a built one does and owns copies
     of the file's sections; the bytes may be freed once the load returns, unless it was loaded
     with KDRT_LOAD_IN_PLACE, whose tree uses them until kdrt_tree_free().

   THREAD SAFETY
     No global state. The functions taking a const kdrt_tree read it only, allocate nothing and
     may be called from any number of threads at once (kdrt_intersect(), kdrt_occluded(),
     kdrt_intersect_k(), the _query variants, the inspection functions, kdrt_hit_surface(),
     kdrt_spawn_ray(), kdrt_closest_point(), kdrt_overlap_box(), kdrt_overlap_sphere());
     kdrt_tree_free() must wait until none is running. Builds of different
     trees may run at once, and one SAH build may run its tasks on many threads through
     options.scheduler, which then calls options.allocator from those threads. kdrt_tree_save()
     reads a const tree (and its mesh buffers) and may run beside queries and other saves; loads
     are as builds: any number at once, of different trees, from the same bytes too.

   ERRORS
     Functions that can fail return kdrt_result; kdrt_result_string() names each code. A failed
     build frees everything it allocated and leaves *out_tree NULL. The library never prints,
     never aborts on bad input and never calls exit(). Checked: NULL pointers, a stride under 12
     bytes, indices out of range, NaN or infinite coordinates (error, or skipped with
     KDRT_BUILD_SKIP_INVALID_TRIANGLES), counts beyond what the tree can address, and allocation
     failure. Zero triangles is valid: the tree is empty and every ray misses. A load checks every
     field of the file before it uses it (SAVED TREES), with result codes of its own.

   QUERIES AND GUARANTEES
     A ray is org + t * dir for t in [max(tmin, 0), tmax]; dir need not be normalised. A ray with a
     NaN or infinite origin or direction, an all-zero direction, a NaN tmin or tmax, or
     tmin > tmax misses everything.
     kdrt_intersect() returns the nearest hit in that range. Equal distances are broken towards the
     lower triangle index, so the result does not depend on the order of the tests: a tree of any
     builder and leaf size returns exactly what max_leaf_size = 0 (test every triangle) returns
     for the same ray, with one exception: a triangle that a ray misses by less than the test's
     rounding error but still "hits" can lie beyond a split plane the ray never crosses, and the
     tree, rightly, never tests it. kdrt_intersect_k() returns the k nearest in the same order,
     (t, triangle), each as kdrt_intersect() would report it, with the same exception.
     A kdrt_query narrows which hits count, for the nearest, any and k nearest hits alike: the
     front or back faces culled (the side is the sign of the test's own determinant, so it is
     the side the hit is on, even for a ray all but in the plane), and a filter callback asked
     about each candidate before it is taken. The answers are those of the same query testing
     every triangle, the hits that do not count left out.
     Triangles are intersected in single precision with no epsilon; a ray meeting a triangle
     exactly on its edge counts as a hit. options.intersector picks the test for a tree:
       KDRT_INTERSECTOR_WATERTIGHT (the default; Woop, Benthin & Wald 2013): a ray that crosses a
         surface made of triangles sharing edges and vertices (by index or by equal coordinates)
         hits at least one of them, even exactly through an edge or a vertex: no ray slips
         through a closed mesh. This holds whatever the compiler fuses into FMAs (-march=native,
         -ffp-contract=fast, Clang on ARM): the edge functions are formed in double, where the
         products of floats are exact. Being in double, they also keep their range: scenes
         from 1e-30 to 1e30 across are traced as at 1 (coordinates near the largest float,
         3.4e38, whose differences overflow, are missed).
       KDRT_INTERSECTOR_FAST (Moeller & Trumbore 1997): a few operations less, but rays through
         an edge or vertex can pass between the triangles sharing it. It computes in float,
         where its products of three lengths (the direction's, the triangle's edges, the
         origin's distance) overflow or underflow unless each lies between about 1e-9 and 1e12:
         beyond, its answers are not defined (usually misses).
     A ray lying exactly in a triangle's plane and meeting it may hit it or miss it: the
     watertight test shears with a rounded dir ratio, which turns the triangle seen edge-on into
     a sliver, and that freedom is what keeps a ray leaving a closed mesh through an edge of such
     a triangle from slipping through. The t of such a hit is a quotient of rounding errors: it
     lies where the ray is within the triangle's bounding box, and no closer to the truth.
     Both tests agree with a double-precision reference on the triangle and, to a few ulps, on t
     everywhere else. A hit's t, u and v are finite: a test whose values leave float's range
     reports no hit. There is no double-precision query: the vertices are floats already.
     Zero-area triangles (coincident or collinear corners: the edges' cross product, evaluated
     in double precision, is exactly zero) are left out of the tree at build time and never hit;
     they are valid input, counted in kdrt_build_report.degenerate_triangles.
     Hits are accepted wherever they are found and the traversal stops only once every node
     nearer than the best hit has been visited, so a hit lying beyond the leaf it was found in
     is never returned ahead of a nearer one. Split-plane distances are widened by a bound on
     their rounding error (pbrt's gamma(3)), and rays lying exactly in a split plane visit both
     sides, so rounding cannot make the traversal skip a node the ray passes through.
     Barycentrics: the hit point is (1 - u - v) * p0 + u * p1 + v * p2.
     Secondary rays: start them with kdrt_spawn_ray(), which offsets the hit point along the
     geometric normal by a distance relative to its magnitude, so a reflected, refracted or shadow
     ray does not hit the surface it leaves, however far from the origin the scene lies.

   THE TREE
     KDRT_BUILDER_MEDIAN is the original course ray tracer's kd-tree, corrected: a node holding at
     most max_leaf_size triangles is a leaf; otherwise it is split at the median triangle centroid
     on its axis, which cycles x, y, z with depth; a triangle goes to every side it has a vertex
     strictly inside (a triangle lying in the split plane goes below). If that axis leaves a child
     as large as the node, the next axes of the cycle are tried, and if none separates anything the
     node is a leaf. Triangles are sorted once per axis at the root and the children's lists are
     filtered from their parent's in order, so a level costs O(n). Depth is bounded by
     options.max_depth (at most KDRT_MAX_DEPTH), which bounds the traversal's fixed stack.
     KDRT_BUILDER_SAH chooses each split by the surface area heuristic (Wald & Havran 2006), at
     the quality options.quality names (bench/README.md measures the three):
     - KDRT_BUILD_QUALITY_MEDIUM, the default: a node with more than KDRT_SAH_EXACT_MAX (128)
       triangle references is binned: KDRT_SAH_BINS (256) equal bins per axis, the planes
       between them costed from counts of the triangles' box faces, O(n); where no plane between
       bins beats a leaf, every candidate below is tried before the node is made one. At or below
       KDRT_SAH_EXACT_MAX every face of every triangle's box on every axis is a candidate: the
       start, end and planar events are sorted once where a subtree comes down to that size and
       kept in order from there (Wald & Havran's O(n log n) build): a split renumbers the events
       of the triangles on one side, and only the events of the triangles it cuts are made again
       and sorted.
     - KDRT_BUILD_QUALITY_HIGH: every candidate at every node, the events sorted once at the
       root and kept in order from there: the lowest SAH cost, the slowest build.
     - KDRT_BUILD_QUALITY_FAST: every node binned, into 32 bins per axis, and never an exact
       sweep; a triangle the plane cuts is not clipped but its box is cut at the plane, so a
       leaf may refer to a triangle that only its box reaches (a test more, never a wrong
       answer). For geometry rebuilt often: meshes that move, load or stream in.
     With MEDIUM and HIGH a triangle cut by the plane is clipped to the node's box and that
     polygon split by the plane (perfect splits), so it goes only where some of it lies. A node
     becomes a leaf when it holds at most max_leaf_size triangles, at max_depth, or when no
     split within its reference budget is cheaper than testing all its triangles (the costs are
     options). A leaf is priced by its blocks of 8 triangles (KERNELS), ceil(n / 8) block tests,
     not n triangle tests, so the SAH stops where one block test is cheaper than more splits: on
     the meshes of bench/README.md leaves of about 20 triangles, half the references and a
     fourteenth of the nodes of triangle pricing, 2.8 times faster builds and 30 to 50% faster
     rays on both kernels. It is the default (KDRT_BUILDER_DEFAULT and
     kdrt_default_build_options()).
     Reference budget: a triangle a plane cuts is referred to on both sides, and some inputs (a
     fan of triangles round one vertex, crossing slivers) would multiply references without
     end. The root's budget is KDRT_SAH_REFERENCE_BUDGET (8) references a triangle; a split is
     made only if its children hold at most their node's budget together, and they share it in
     proportion to what each holds. So every level of the tree holds at most 8 n references
     (n: the triangles in the tree), which bounds the build whatever the input: the tree's
     references at most 8 n (in blocks of 8, 40 bytes a reference, and a leaf's last block
     partly filled), its nodes at most 12 n a level (an inner node holds 2 references or
     more); the build's reference arrays at most 8 n at any moment
     (28 bytes each: above the exact region each node's array is freed once its children have
     theirs), and sorted events for at most one budget's worth at a time (48 bytes a
     reference; with HIGH, the top's tasks hold theirs until they run: a budget's worth
     more); O(n) work a level, sorts included (long ones are radix sorts), over at most
     max_depth levels: O(n log n) with the default max_depth. Ordinary meshes stay far below
     the budget and keep their trees; a fan of triangles round one vertex gets big
     leaves round it instead of references without end.
     Parallel build: the top of the tree (nodes of more than 4096 triangles, down to depth 6) is
     split on the calling thread, its nodes of 16384 references or more binned in 16 chunks that
     are tasks on options.scheduler (HIGH: the root's events sorted an axis a task); the subtrees
     below, at most 64, are independent tasks too, then joined in depth-first order. Checking
     the triangles before and packing the leaf blocks after are tasks in 16 chunks as well. The
     cut and the chunks depend only on the input, so the tree is the same for any scheduler,
     thread count or task order, and without one. The scheduler's run() is called several
     times a build: a scheduler should keep its threads.
     max_leaf_size = 0 means no tree: every query tests every triangle, through the same API.
     Memory, whatever the builder: 8 bytes a node (pbrt-v3's layout), then the triangles the
     intersection tests read, copied at the end of the build so that a test does not chase the
     caller's index buffer to three scattered vertices: each leaf's triangles in blocks of 8
     (320 bytes: the 9 corner coordinates of 8 triangles and their indices; a triangle crossing
     leaves is in each), the leaves' blocks in depth-first order, and 4 bytes a block for the
     inspection API, then each leaf's box and ropes and each node's leaf number (START CELLS:
     48 bytes a leaf, 4 a node). A soup costs what its indexed mesh does; skipped and zero-area
     triangles are not copied. kdrt_tree_stats.bytes counts it all: 79 to 84 bytes a triangle
     on the meshes of bench/README.md (74 to 79 without the cells).
     Inspection: kdrt_tree_node_count(), kdrt_tree_node() (a node's kind, split, children, box,
     depth and leaf references) and kdrt_tree_reference() (the caller's triangle a reference
     names) walk a built tree without its internals.

   START CELLS
     A kd-tree's leaves tile its box, so a ray that starts inside it can start in the leaf that
     holds its origin and walk from leaf to leaf, instead of descending from the root to that
     leaf first: most of a secondary ray's node steps (Havran's ropes; Popov et al. 2007). Every
     tree keeps, for each leaf (a cell), its box and six ropes, one across each face to the
     smallest node whose box covers that face (none on the tree's boundary): 48 bytes a leaf and
     4 a node, in kdrt_tree_stats.bytes. kdrt_ray.cell names the cell to start in: kdrt_hit.cell
     (the leaf that holds a hit point), kdrt_spawn_ray() (which sets it for the ray it makes), or
     kdrt_locate(tree, point) for a camera, light or eye inside the scene, whose rays then share
     one descent. 0, as in a {org, tmin, dir, tmax} initialiser, starts at the root (compilers'
     -Wmissing-field-initializers asks for the fifth member: write 0).
     A cell is only a hint. It is used when it names a leaf of this tree whose box holds the
     origin strictly inside (exact float comparisons); any other value (out of range, an inner
     node, another tree's, a stale one after a rebuild, a neighbour, an origin on the cell's face)
     starts at the root, so no hint can change an answer. From the cell, the walk tests the
     leaf's blocks, stops when the best hit lies before the ray leaves the cell, else follows the
     rope of the face it leaves by and goes down to the leaf it enters, deciding each plane as the
     root walk does, with the same rounding bound; where that bound leaves the way in doubt (the
     ray leaves near an edge or a corner of a cell, or crosses a plane about where it enters the
     next), it goes on with the walk from the root over the rest of its range. Every query takes
     the hint: kdrt_intersect(), kdrt_occluded(), the _query forms, kdrt_intersect_k(), and the
     scene queries for the scene's mesh tree (instances start at their root; kdrt_scene_locate()
     and kdrt_scene_spawn_ray() give the mesh tree's cells). The answers are the walk from the
     root's, bit for bit (the tests compare the two on millions of rays of every kind), with the
     exception QUERIES AND GUARANTEES names: a triangle missed by less than the test's rounding
     that still "hits" may lie in a leaf one walk visits and the other does not.

   BATCHES
     kdrt_intersect_batch() and kdrt_occluded_batch() (and their scene forms) trace an array of
     rays, each answered exactly as the single-ray call answers it, every field of kdrt_hit (a
     miss's too), whatever the batch's size, order or content. With the AVX-512 kernel each 16
     consecutive rays form a packet, with the AVX2 kernel each 8, when their directions have no
     zero component and share their signs and their largest axis, and their origins and
     directions lie close together: a camera's rays in 4x4 pixel tiles (4x2 for packets of 8),
     the shadow rays of those pixels to one light. The packet walks the tree once: at each plane
     every lane takes the decision its own walk from the root takes, all lanes at once; a leaf's
     triangles are culled for the whole packet (rigorous bounds on what the watertight test
     computes for each ray), and each one left is tested against the packet's rays at once, with
     the test's own operations in each lane. Other rays go one by one: odd ones, incoherent
     groups (after groups that form no packet, the next ones do not try, and are tried again
     only when most of their directions share their signs), and in kdrt_intersect_batch() rays
     with a start cell, whose rope walk names their kdrt_hit.cell (kdrt_spawn_ray() sets one; a
     cell of 0 lets a ray into a packet). So do queries with flags, a filter or a mask to test,
     the scalar kernel's batches, and a scene's instances (its mesh tree walks in packets when
     every mesh's mask has every bit). Arrays are contiguous, without a stride: the packets
     gather 8 or 16 rays at a time, and a caller whose rays live in its own structures copies
     them into a kdrt_ray array for far less than tracing them costs. Nothing is allocated (a
     call's stack is about 16 KB with the AVX-512 kernel, 11 KB with the AVX2 one: GCC 12 at -O3,
     -fstack-usage); any number of threads may call at once.

   KERNELS
     A tree's queries run one of five kernels, chosen when it is built and kept in the tree (no
     global state); kdrt_tree_stats.kernel says which. On x86-64 (GCC, Clang, clang-cl, MSVC):
     the AVX-512 kernel if the CPU has AVX512F, else the AVX2 kernel if it has AVX2, else the
     scalar kernel, the CPU and the OS's saving of its registers asked when the tree is built
     (PLATFORMS); KDRT_BUILD_AVX2_KERNEL and KDRT_BUILD_SCALAR_KERNEL ask for the narrower ones.
     On aarch64 the NEON kernel, and on WebAssembly built with -msimd128 the SIMD128 kernel,
     chosen at compile time (the target always has them); KDRT_BUILD_SCALAR_KERNEL asks for the
     scalar one there too. Elsewhere, and under KDRT_NO_SIMD, the scalar kernel.
     All walk the same tree and read the same 8-wide leaf blocks. The AVX2 kernel tests a block's
     8 triangles at once, NEON and SIMD128 as two halves of 4 (the watertight test's doubles 2 at
     a time), each with the scalar test's operations in the same order, so every kernel returns
     the same answers bit for bit (the tests compare them on 1.4 million rays, and
     tests/platforms/answers.txt across platforms: PLATFORMS). Before the exact watertight test,
     the SIMD kernels leave a block early when float products already prove that the ray misses
     its triangles: a filter that changes no answer. The AVX-512 kernel is the AVX2 kernel with a
     batch's packets 16 rays wide; the packet code is written once over the vector width, and the
     implementation includes the header again (KDRT_HEADER_FILENAME) to compile it for 8 lanes and
     for 16; its operations name their rounding, which no compiler fuses. NEON and SIMD128
     batches walk one ray at a time, with the block tests. No compiler flag is needed: the x86
     SIMD functions carry the per-function target attribute (MSVC needs none). Measured: the
     NEON kernel runs 2.1x (GCC 12) to 2.6x (Clang 14) fewer instructions a ray than the scalar
     kernel on aarch64, the SIMD128 kernel 2x the scalar kernel's rays a second under node 20
     (tests/platforms/count_instructions.sh, kernel_speed.c). The SAH builder bins references with
     SSE2 on x86-64 (no attribute needed) and costs the planes between bins 8 at a time with AVX2
     where the CPU has it (4 at a time with SSE2 where not), each lane rounding as the scalar code
     does, so the tree is the same; KDRT_BUILD_SCALAR_KERNEL builds with the scalar code too.

   PLATFORMS
     The file with the implementation needs no flag anywhere: no -mavx2, -march or /arch.
       x86-64, GCC and Clang (Linux, macOS, mingw-w64): AVX-512, AVX2 or scalar, the CPU asked
         by __builtin_cpu_supports (mingw: link libgcc, e.g. -static)
       x86-64, MSVC and clang-cl: the same kernels, the CPU asked by __cpuid and _xgetbv (its
         features, and the OS saving the YMM and ZMM registers), with nothing beyond the CRT;
         cl.exe's warning C4752 is silenced by the header
       aarch64 (GCC, Clang: Apple silicon, ARM consoles and phones, Linux): NEON
       WebAssembly (emscripten): SIMD128 with -msimd128, else scalar
       elsewhere (i386, MSVC on ARM64, 32-bit ARM, RISC-V): scalar
     The same bits on every platform, for every query and every kernel: each operation rounds
     once, as written, in float or in double. A compiler that fuses a multiply and an add into
     an FMA changes last bits, and compilers do by default in places (GCC in its GNU modes, which
     CMake's defaults are; Clang where the target has FMA: -march=haswell, aarch64), so the
     implementation turns contraction off for itself (#pragma GCC optimize, Clang's fp contract,
     MSVC's fp_contract) and restores it after where the compiler can; NEON's products also pass
     an empty asm, which no fusing sees through. Clang alone ignores its pragma under an explicit
     -ffp-contract=fast: leave that flag off this file. i386's x87 arithmetic keeps 80-bit
     intermediates and cannot match: it stops the compilation with an #error naming -msse2
     -mfpmath=sse (MSVC: /arch:SSE2), as -ffast-math and /fp:fast do (CONFIGURATION).
     tests/platforms/answers.txt holds 640 rays and the bits of every answer; CI checks it on
     x86-64 with every kernel (GCC, Clang, GNU modes, -march=native, -O0), i386 with SSE2,
     mingw-w64 under wine, MSVC's target (compiled by clang as clang-cl and with cl.exe's
     macros, then run under wine: there is no cl.exe here), aarch64 under qemu and WebAssembly
     under node, scalar and SIMD128.
     Stack, for fiber and job stacks (x86-64, GCC 12 -O2, tests/platforms/stack_usage.c): a query
     (kdrt_intersect, kdrt_occluded, kdrt_intersect_k) 1.6 KB on the scalar kernel, 2.7 KB on the
     AVX2 and AVX-512 ones (their frames are 32-byte aligned); a batch call 2.5 KB scalar, 12 KB
     AVX2, 19 KB AVX-512; a build 19 KB for a tree 29 deep, and by its frames' sizes about 470
     bytes more a level, so about 35 KB at KDRT_MAX_DEPTH. A parallel build's tasks need as much
     on each thread.

   SCENES
     A kdrt_scene puts many geometries behind one query, as an engine has them. Each entry
     (kdrt_geometry) carries the caller's 32-bit ID, a 32-bit mask and a user pointer, and is
     either a mesh (a kdrt_triangles view, borrowed) or an instance (a tree built once by
     kdrt_tree_build(), borrowed, placed by a 3x4 affine transform; one tree may be placed any
     number of times). The scene's meshes are built into one tree together, so a static world
     costs what one mesh of all their triangles would; the instances sit under a small top level,
     a 4-wide BVH over their world boxes binned by the boxes' centres (each instance in one leaf,
     as in Embree and tinybvh; a ray meets a node's four boxes in one SSE2 slab test on x86).
     Zero entries, meshes only and instances only are valid scenes.
     Changes: kdrt_scene_set_transform() moves an instance, kdrt_scene_attach() adds an entry,
     kdrt_scene_detach() removes one and kdrt_scene_enable() turns one off and on (a disabled
     entry keeps its ID and is seen by no query), each from the next kdrt_scene_commit() on;
     until then queries see the scene as it was. A commit places the moved and added instances
     and rebuilds the top level, in memory the scene keeps from commit to commit (a commit that
     adds and removes no ID allocates nothing once the scene has held as many instances), on
     options.scheduler from 2,048 instances; the same top level on any scheduler. The scene's
     meshes are built once: attaching or detaching a mesh rebuilds the whole mesh tree at the
     next commit (a static world's cost), while disabling one rebuilds nothing. A deforming mesh
     belongs in a tree of its own, placed as an instance: build its new tree, detach the old
     instance, attach one of the new tree under the same ID, commit, then free the old tree. A
     failed commit leaves the scene as it was, its changes pending.
     IDs are unique within a scene: a duplicate is refused (KDRT_ERROR_INVALID_GEOMETRY_ID), so a
     hit names one entry and ties have one answer. A hit reports the geometry's ID
     (kdrt_hit.geometry) and the triangle's index within its mesh (an instance's: within its
     tree's mesh), and kdrt_hit.instance is the instance's ID for a hit through one
     (KDRT_INVALID_ID otherwise). Equal t goes to the lower geometry ID, then the lower triangle.
     A kdrt_query works on scenes as on trees, for nearest, any and k nearest hits: its mask
     skips every geometry whose mask shares no bit with it (an instance before its tree is
     walked, a mesh's triangles as candidates), its flags cull faces, its filter is asked about
     each candidate, whose geometry and instance are filled in. Faces are judged in the world:
     an instance whose transform mirrors (negative determinant) reverses its triangles' winding,
     so its front and back swap, and kdrt_scene_hit_surface()'s normal turns with them.
     Exactness: hits on the scene's own meshes are exactly what one tree over them returns,
     every guarantee of QUERIES AND GUARANTEES included. A ray meeting an instance's box is
     carried into the tree's space by the inverse transform, evaluated in double and rounded to
     float once, and the hit is the exact answer for that ray (as in Embree and every
     instancing tracer): within float rounding of the world-space answer, not bit for bit. The
     direction is not renormalised, so t is the same parameter in both spaces and hits from
     anywhere in the scene compare directly. An instance's world box is its tree's box
     transformed, widened by 2^-20 of its extent and position for the rounding. That box must be
     finite: an instance whose box would reach beyond float's range (a tree 1e10 across under a
     scale of 1e30, or one whose corners lie within 2^-20 of the largest float) is refused with
     KDRT_ERROR_INVALID_TRANSFORM, by kdrt_scene_build() (report naming it) and by
     kdrt_scene_set_transform() (the scene unchanged), so the top level only ever bins and clips
     finite boxes. A world ray whose trip into an instance's space leaves float's range (its
     origin beyond 3.4e38 there, as under a scale of 1e-10 from 1e30 away) misses that instance,
     as any ray with an infinite origin misses (QUERIES AND GUARANTEES).
     Ownership: the meshes' buffers and the instances' trees must stay alive and unchanged until
     kdrt_scene_free(), or until the commit after their entry's kdrt_scene_detach(); an instance
     of a freed tree is the caller's error, which kdrt cannot detect. Threads:
     queries as on trees (const scene, nothing allocated, any number at once); the changes and
     kdrt_scene_commit() change the scene and must not overlap a query on it, nor each other.
     Baked scenes: a level's static meshes are the scene's mesh tree, and building it is most of
     a scene build. kdrt_scene_save_meshes() saves that tree as kdrt_tree_save() saves one (SAVED
     TREES; a scene without meshes saves a file of none), and kdrt_scene_load() is
     kdrt_scene_build() with the tree loaded from those bytes instead of built, as a tinybvh or
     Embree user bakes and loads an acceleration structure:

         kdrt_scene_build(entries, count, &options, &scene, NULL);       // offline, once
         kdrt_scene_save_meshes(scene, write_to_file, file);
         ...
         r = kdrt_scene_load(entries, count, bytes, size, NULL, &scene, &report); // at run time
         if (r == KDRT_ERROR_MESH_MISMATCH) ... // report.invalid_geometry: the mesh that changed

     The entries must hold the same meshes under the same IDs (their buffers the same floats and
     indices, checked by the file's fingerprint of each); their order, masks, flags and user
     pointers, and the instances, are free to differ, since the file holds none of them: the
     instances are placed and the top level built as kdrt_scene_build() does, which costs little
     beside the mesh tree. The scene takes the file's build options for the mesh trees later
     commits rebuild (attaching or detaching a mesh), with the allocator, scheduler and kernel
     flags of the options given (NULL: defaults); KDRT_LOAD_IN_PLACE borrows the bytes until
     kdrt_scene_free() or the commit that rebuilds the mesh tree. A loaded scene answers every
     query bit for bit as the scene that was saved. kdrt_tree_save()'s file of a tree is a scene's
     file of one mesh with ID 0, and loads as such.

   SAVED TREES
     A built tree saved once loads in a fraction of its build's time: a game bakes its static
     geometry offline and loads it at start, as tinybvh's and nanort's users do.

         static int to_file(void *file, const void *bytes, size_t size)
         {
             return fwrite(bytes, 1, size, (FILE *)file) == size;
         }
         kdrt_tree_save(tree, to_file, file);          // offline: kdrt_tree_saved_size() bytes
         ...
         r = kdrt_tree_load(bytes, size, &mesh, NULL, &tree, NULL);   // the same mesh buffers
         if (r == KDRT_ERROR_MESH_MISMATCH) ... // the mesh changed since: build (and save) again

     A loaded tree answers every query bit for bit as the saved tree, on every kernel and
     platform (the file is little-endian everywhere, its floats the tree's own bits), and saves
     again to the same bytes. The bytes do not depend on the run, the kernel, the scheduler or
     the thread count, since builds do not (THE TREE, KERNELS). The load's options give the
     allocator and the kernel flags, the kernel chosen as a build chooses it; the file gives the
     rest: the tree, its intersector and the build options it records, which
     kdrt_saved_tree_read_info() reads for tools without loading. A file is the tree's memory as
     it lies, its size within 0.1% of kdrt_tree_stats.bytes (the cells included).
     Checked before use, in one pass over the nodes and one over the blocks, with a result code for
     each kind of failure, *out_tree NULL and nothing left allocated:
       KDRT_ERROR_NOT_A_SAVED_TREE  no magic; KDRT_ERROR_FILE_BYTE_ORDER a big-endian byte order
       mark; KDRT_ERROR_FILE_VERSION another format version; KDRT_ERROR_FILE_SIZE fewer or more
       bytes than the header records (every truncation); KDRT_ERROR_MESH_MISMATCH meshes other
       than those saved (their number, IDs, counts, soup or indexed, or the XXH64 fingerprint of
       their positions and indices, read through any stride: a strided copy of the same floats
       is the same mesh); KDRT_ERROR_OUT_OF_MEMORY; KDRT_ERROR_FILE_CORRUPT anything else: the
       header's checksum, every header field in range and consistent (sizes against counts and
       the file's size, options valid, depths within the limit the options resolve to, bounds
       finite or the empty box), the nodes in the depth-first layout a build makes (children in
       range, each below child next and each above child reached exactly where its sibling's
       subtree ends: no cycle, no node twice, depth at most the limit and KDRT_MAX_DEPTH), splits
       finite and within their node's box, each leaf's blocks and references where the counts
       before it put them, every lane's triangle below the meshes' count, each leaf's last block
       padded with copies of its last triangle as the build pads it, every cell's box the walk's
       bit for bit, its ropes nodes of the tree or none, the cell map, and last the checksums of
       the mesh records and of the sections.
     The checksums find damage: any changed word. A forged file (its checksums made again)
     passes only if it is a well-formed tree: its queries then cannot crash, hang, read out of
     bounds or allocate, but they answer as its bytes say, since the triangles' corners and the
     ropes are not compared with the mesh's (that would cost the gather through the index buffer
     that a build's packing costs). A load allocates at most the file's size and 63 bytes beside
     the tree's struct (320 bytes on x86-64); with KDRT_LOAD_IN_PLACE, where the bytes are 64-byte
     aligned and the host little-endian, only the struct: the tree then uses the bytes where they
     lie (their blocks, nodes and cells), which must stay alive and unchanged until
     kdrt_tree_free(). tests/test_save.cpp refuses every truncation, extra byte, changed byte and
     forged field of a saved tree; tests/fuzz/fuzz_load.cpp fuzzes loads under ASan and UBSan.
     Across platforms: tests/platforms/answers.c loads four trees saved on x86-64 (a scene's mesh
     tree among them; tests/platforms/answers.kdrt) on each target tests/platforms/run.sh runs it
     on (x86-64 and i386, aarch64 under qemu, wasm under node, mingw-w64 under wine), copied and
     in place with each kernel there, and checks that they give its stored answers bit for bit
     and save again to the same bytes.
     Cost, one thread, on an AMD EPYC 2-core VM with AVX2 (GCC 12, Release build; kdrt-bench
     --save-load, the fastest of 7 rounds, its commands in bench/README.md, "Saved trees", with
     other builds running beside it), against a FAST build of the same mesh:
         mesh (triangles)          FAST build   load (x faster)  in place (x)   hash   save  file
         stanford-bunny (69,451)     31.8 ms    1.19 ms (27)     0.83 ms (38)   0.12   1.33  5.8 MB
         ogre (124,008)              64.9 ms    2.84 ms (23)     1.72 ms (38)   0.23   2.90  11.6 MB
         bunny subdivided twice     601 ms     67.1 ms  (9.0)   12.8 ms  (47)   1.91   21.6  93.4 MB
           (1,111,216)
     "hash" is the mesh fingerprint, XXH64 over the positions and indices (1.2 MB for the bunny,
     20 MB for the subdivided one), which every load computes: a tenth of the small loads, 3% of
     the large one. A copying load of a large tree is bound by the fresh memory it writes (a page
     fault every 4 KB): 93 MB of blocks cost it most of its 67 ms, which a load in place does not
     spend.
     The format, version 1 (KDRT_SAVED_TREE_VERSION): little-endian, uint32 and float (IEEE
     binary32 bits) words, uint64 as two words, low first. A 256-byte header, then the sections
     in this order, each its records back to back with nothing between:
       offset  header field
         0     magic "KDRTTREE" (8 bytes)
         8     byte order mark 0x01020304 (bytes 04 03 02 01)
        12     format version: 1
        16     header size in bytes: 256
        20     mesh records (1 for a tree; a scene's meshes, 0 or more)
        24     file size in bytes (uint64)
        32     section sizes in bytes (uint64 each): mesh records, nodes, blocks, block
               references, cells, cell map (at 32, 40, 48, 56, 64, 72)
        80     nodes, leaves, blocks, triangles in the tree (kdrt_tree_stats)
        96     triangle references (uint64)
       104     depth of the deepest leaf; 108 the meshes' triangles, all of them
       112     build options as given: builder, quality, intersector, max_leaf_size, max_depth
               (112 to 128); 132 the depth limit the build resolved; 136 flags (only
               KDRT_BUILD_SKIP_INVALID_TRIANGLES); 140, 144, 148 sah_traversal_cost,
               sah_intersection_cost, sah_empty_bonus (floats, 0 for the default)
       152     the build's KDRT_SAH_BINS, KDRT_SAH_EXACT_MAX, KDRT_SAH_REFERENCE_BUDGET
       164     the tree's bounds: min x, y, z, max x, y, z (floats); kdrt_aabb_empty() when empty
       188     0
       192     XXH64 of the mesh records (uint64)
       200     checksum of the sections from blocks to cell map (uint64, below)
       208     0 up to 248
       248     XXH64 of bytes 0 to 247 (uint64)
       blocks         320 bytes each, 64-byte aligned in the file: 9 x 8 floats, [3 * corner +
                      axis][lane], the corners of 8 triangles, then their 8 triangle numbers
                      (across the meshes: mesh k's triangle i is the sum of the earlier meshes'
                      counts plus i); each leaf's triangles in ceil(count / 8) blocks, leaf by
                      leaf in node order, the last block's spare lanes copies of its last lane
       nodes          8 bytes each, depth first, the below child after its parent: word 0 the
                      split (float) of an inner node or a leaf's first block; word 1 the axis
                      (bits 0-1: 0, 1, 2, or 3 for a leaf) and above it (bits 2-31) an inner
                      node's above child or a leaf's triangle count
       cells          48 bytes a leaf, in node order: its box (min x, y, z, max x, y, z floats)
                      and six ropes, [2 * axis + side], a node or 0xFFFFFFFF (START CELLS)
       block refs     4 bytes a block: the number of its lane 0's reference, leaf by leaf
       cell map       4 bytes a node: a leaf's number among the leaves, 0xFFFFFFFF for an
                      inner node
       mesh records   32 bytes a mesh, in the tree's order (a scene's: by ID): its ID, triangle
                      count, vertex count, 1 if indexed else 0, XXH64 of its vertex_count * 3
                      position floats (as little-endian bytes, vertex by vertex whatever the
                      stride), XXH64 of its 3 * triangle_count indices (of no bytes for a soup);
                      a mesh of no triangles hashes no bytes at all
     XXH64 is xxHash's 64-bit hash with seed 0, which every xxHash library computes. The sections'
     checksum is a Fletcher sum over their words in file order, in 8 lanes: word i adds to a[i mod
     8], then a[i mod 8] adds to b[i mod 8], 32-bit and wrapping; it ends as XXH64 of a[0..7] and
     b[0..7] (32-bit words) and the number of words (uint64), 72 bytes. A reader of another
     version or byte order stops at its field; a newer version would change the number at 12.

   CLOSEST POINT AND OVERLAP
     Beyond rays, the same trees and scenes answer two spatial queries, with no extra memory:
     kdrt_closest_point() gives the nearest point of any triangle to a point (its triangle,
     barycentrics, distance), within max_distance (closed; INFINITY: anywhere); nothing
     (triangle KDRT_INVALID_ID, distance INFINITY) when no triangle is that near. Equal distances
     go to the lower triangle index, so every builder, leaf size and kernel returns what
     max_leaf_size = 0 returns, bit for bit. kdrt_overlap_box() and kdrt_overlap_sphere() call a
     callback once for each triangle that meets a closed box or ball, each triangle once, in no
     particular order, and count them; a callback returning 0 stops the query, and the count
     includes the triangle it stopped at. A box with min > max on an axis is empty, a flat one
     (min == max) is a rectangle, a segment or a point, an infinite bound a half-space; a radius
     of 0 is the centre alone, INFINITY every triangle. A NaN or infinite point or centre, a NaN
     or negative max_distance or radius, or a NaN bound is refused (KDRT_ERROR_INVALID_QUERY:
     nothing found, counted or called). Zero-area triangles are left out of a tree (as for rays:
     kdrt_build_report.degenerate_triangles), so these queries never find them either.
     Distance. Computed in double in the point's own frame (the corners moved by -point), by
     Ericson's regions with cross products formed by fma, then rounded to float once: with D the
     true distance to the nearest triangle and R the largest distance from the point to a corner
     of the triangles compared (the one returned and a truly nearest one), the distance returned
     is D give or take 2^-44 R, rounded to the nearest float, so |d - D| <= 2^-24 D + 2^-44 R
     (D a normal float; one beyond the largest float is INFINITY, its triangle still named). A
     point on a triangle gets 0 or at most 2^-44 of its reach; one off the surface, D to within
     float rounding. The triangle returned is a nearest one within that bound, and point is
     (1 - u - v) p0 + u p1 + v p2 on it, rounded to float inside its corners' box. The walk
     visits nodes nearest first (a queue ordered by their boxes' distances) and skips nodes and
     triangles whose boxes, or whose corners seen along the direction of the best point so far,
     lie farther than the best so far, with a margin that rounding cannot cross (2^-40 of the
     distance and 2^-43 of the farthest corner of the tree's box: the error of a sliver's
     distance grows with its far corner, and none that could tie or win is left out). With
     AVX2 and FMA it measures the triangles left in a block 4 at a time, by the same operations
     as the scalar kernel, so with the same answers bit for bit.
     Boxes are decided exactly: the separating axis test of the triangle and the box (the box's
     3 axes, the triangle's normal, its 3 edges crossed with the 3 box axes; Akenine-Moeller
     2001) where each axis' verdict is exact: float comparisons on the box's axes, and on the
     others the sign of a sum of products of floats, taken from the sum in double when its error
     bound allows and otherwise from the exact sum (Shewchuk's expansions, as in orient3d). A
     triangle touching the box at a corner, along an edge or in a face meets it; one a float
     beyond it does not. Balls: a corner in the ball decides exactly (|p - c|^2 <= r^2 summed
     exactly), else the distance above is compared with the radius, so only an edge or a face
     within that bound of the sphere may go either way; a triangle must also meet the ball's box
     (centre +- radius rounded outwards, decided exactly as for boxes), so that every tree
     reports what max_leaf_size = 0 reports.
     Scenes: kdrt_scene_closest_point() and kdrt_scene_overlap_box() / _sphere() take a mask (as
     kdrt_query.mask: enabled geometries sharing a bit with it) and measure in the world. Ties
     go to the lower geometry ID, then the lower triangle; a report names the geometry, the
     triangle in its mesh and the instance. An instance's triangle is its tree's with each
     corner carried by the transform in double and rounded to float, and the guarantees above
     hold for those world triangles (one flattened by rounding is still tested, as a segment or
     a point). Under a non-uniform scale or a shear the nearest triangle in the tree's space is
     not always the nearest in the world, and the walk does not assume it: a node's world
     distance is bounded below by its distance in the tree's space over the Frobenius norm of
     the inverse transform, less the rounding. A box or ball goes into an instance's space as
     the box round its corners there (widened by the rounding), and what that box finds is
     tested in the world.
     Cost. A closest point near the surface costs a descent and a leaf or two; the farther the
     point from every triangle, the more nodes lie about as far as the best and are visited;
     when more wait than the queue holds (near the centre of a finely divided sphere, all of it
     about as far), the walk goes over the tree once more, depth first, with the best so far.
     An overlap query visits the leaves its box meets and tests their triangles once each; a
     triangle referred to by several leaves (crossing a split plane) and reaching past the
     split faces of the leaf found in is reported only by the first of them in node order, which
     a second descent from the root, bounded by the triangle's box, finds: big triangles under
     big queries cost that descent each. The queries allocate nothing (the closest-point walk's
     queue of 128 nodes with their distances takes 5 KB of the caller's stack, the overlap
     walk's stack of KDRT_MAX_DEPTH + 1 nodes with their boxes 2 KB) and may run from any number
     of threads; the callback runs on the calling thread and may query the same tree or scene,
     not change it.

   OPTICS
     For refractive objects: kdrt_reflect(), kdrt_refract() (Snell's law), exact Fresnel
     reflectance for smooth dielectrics, and Schlick's approximation of it. Conventions:
     - incident is the direction the light travels, towards the surface; outputs point away from
       it and are unit vectors. Neither incident nor normal needs unit length (kdrt_ray.dir need
       not be normalised either), and the normal may face either side: it is turned internally to
       face the light.
     - eta = eta_incident / eta_transmitted: the index of refraction on the side the light comes
       from over the index on the far side (glass from air: 1 / 1.5).
     - cos_i, taken by the Fresnel functions, is the cosine of the angle of incidence, between
       -incident and the normal facing the light: |incident . normal| / (|incident| |normal|).
     Numerics: everything is computed in double and rounded to float once, with no epsilon.
     kdrt_refract() decides total internal reflection from the sign of
     k = |i|^2 |n|^2 - eta^2 |i x n|^2 (cos^2 of the transmitted angle, scaled), with one rounding
     (fma): exactly at the critical angle k is 0 and the light refracts to the grazing direction
     (incident (1, 0, -0.75), normal (0, 0, 1), eta 1.25), and the decision can only be wrong when
     the exact k is within a few double-precision ulps of 0, far closer than a float input's own
     rounding. The refracted direction is within 2^-22 rad of Snell's law evaluated in
     double at every angle, the ill-conditioned ones near the critical angle included.
     The medium stack is the original course ray tracer's, keyed by object: entering an object
     pushes its index of refraction, leaving it removes that object's entry wherever it is (so
     overlapping and nested media work), and outside_ior (the original's AIR_INDEX_MEDIUM) lies
     below everything. The current medium is the entered one of highest priority, ties going to
     the latest entered. A surface is real when crossing it changes the current medium; otherwise
     it is false and the ray goes straight on (Schmidt and Budge, "Simple Nested Dielectrics in
     Ray Traced Images", JGT 2002): model a glass of water with the water overlapping the glass
     and give the glass the higher priority, and the water's surface inside the glass is ignored.
     Give every object the same priority for the original's plain stack. The stack is fixed-size
     plain data (KDRT_MEDIA_STACK_CAPACITY entries) and a full stack is an error, never a crash.
     At each hit of a transparent object obj, with ior[] and priority[] the caller's:

         kdrt_media_crossing x = kdrt_media_at_surface(&stack, obj, ior[obj], priority[obj]);
         kdrt_result r = KDRT_SUCCESS;
         int crossed = 1;                                   // a false surface: straight on
         if (x.real) {
             float eta = x.eta_incident / x.eta_transmitted;
             if (random01() < kdrt_fresnel_dielectric(cos_i, eta))
                 crossed = 0, kdrt_reflect(dir, normal, dir);
             else                                           // 0: reflected after all (near the
                 crossed = kdrt_refract(dir, normal, eta, dir) != 0; // critical angle); -1: bad
         }                                                  // input, dir unchanged, crossed
         if (crossed)                                       // after a reflection: unchanged
             r = x.entering ? kdrt_media_enter(&stack, obj, ior[obj], priority[obj])
                            : kdrt_media_leave(&stack, obj);
         if (r != KDRT_SUCCESS) ...                         // e.g. a full stack: end the path
         kdrt_spawn_ray(tree, &hit, dir, &ray);             // the next ray, off the surface

   LICENSE
     MIT No Attribution, see the end of this file.
*/
#ifndef KDRT_H
#define KDRT_H

/* The version of this header; kdrt_version() returns the one of the implementation the program
   was linked with (the file with KDRT_IMPLEMENTATION), KDRT_VERSION_STRING when they agree. */
#define KDRT_VERSION_MAJOR 0
#define KDRT_VERSION_MINOR 1
#define KDRT_VERSION_PATCH 0
#define KDRT_VERSION_STRING "0.1.0"

#include <stddef.h>
#include <stdint.h>

#ifndef KDRT_API
#ifdef KDRT_STATIC
#if defined(__GNUC__) || defined(__clang__)
#define KDRT_API static __attribute__((unused))
#else
#define KDRT_API static
#endif
#else
#define KDRT_API extern
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* The deepest tree a build makes; the traversal's stack holds this many entries. A fixed
   constant, not a configuration macro: options.max_depth is the knob, up to this. */
#define KDRT_MAX_DEPTH 64
/* Most triangles a tree accepts (a leaf's count and a child's index are 30-bit fields). */
#define KDRT_MAX_TRIANGLES 0x3FFFFFFFu
/* kdrt_hit.triangle on a miss, and kdrt_build_report.invalid_triangle when none was bad. */
#define KDRT_INVALID_ID 0xFFFFFFFFu

typedef enum kdrt_result {
    KDRT_SUCCESS = 0,
    KDRT_ERROR_NULL_ARGUMENT,      /* a required pointer was NULL */
    KDRT_ERROR_INVALID_STRIDE,     /* position_stride is neither 0 nor at least 12 bytes */
    KDRT_ERROR_INVALID_OPTION,     /* unknown builder or flag */
    KDRT_ERROR_INDEX_OUT_OF_RANGE, /* a triangle refers to a vertex at or past vertex_count */
    KDRT_ERROR_NON_FINITE_VERTEX,  /* a triangle has a NaN or infinite coordinate */
    KDRT_ERROR_SIZE_OVERFLOW,      /* a count or byte size beyond what can be addressed */
    KDRT_ERROR_OUT_OF_MEMORY,      /* the allocator returned NULL */
    KDRT_ERROR_MEDIA_STACK_FULL,   /* kdrt_media_enter() with KDRT_MEDIA_STACK_CAPACITY entered */
    KDRT_ERROR_NOT_IN_MEDIUM,      /* kdrt_media_leave() of an object the stack does not hold */
    KDRT_ERROR_INVALID_IOR,        /* an index of refraction that is NaN, infinite, 0 or negative */
    KDRT_ERROR_INVALID_GEOMETRY_ID, /* a scene's geometry ID used twice, or KDRT_INVALID_ID */
    KDRT_ERROR_INVALID_TRANSFORM,  /* an instance transform that is singular, NaN or infinite,
                                      or that carries its tree's box beyond float's range */
    /* Saved trees (SAVED TREES): */
    KDRT_ERROR_WRITE_FAILED,       /* kdrt_tree_save()'s write callback returned 0 */
    KDRT_ERROR_NOT_A_SAVED_TREE,   /* the bytes do not start with a saved tree's magic */
    KDRT_ERROR_FILE_VERSION,       /* a saved tree of a format version this kdrt does not read */
    KDRT_ERROR_FILE_BYTE_ORDER,    /* a saved tree whose byte order mark is not little-endian */
    KDRT_ERROR_FILE_SIZE,          /* fewer or more bytes than the saved tree's header records
                                      (a truncated file, or bytes after its end) */
    KDRT_ERROR_FILE_CORRUPT,       /* a header or section field that no save writes: a damaged
                                      or forged file */
    KDRT_ERROR_MESH_MISMATCH,      /* the meshes given are not those the tree was saved over
                                      (counts, or the hash of positions and indices) */
    KDRT_ERROR_INVALID_QUERY       /* a closest-point or overlap query's point, box, radius or
                                      distance is NaN, infinite or negative where it may not be */
} kdrt_result;

typedef struct kdrt_aabb {
    float min[3];
    float max[3];
} kdrt_aabb;

/* A borrowed view of the caller's triangles (see OWNERSHIP). */
typedef struct kdrt_triangles {
    const float *positions;    /* x, y, z of vertex 0; vertex i starts i * stride bytes later */
    size_t position_stride;    /* bytes from one vertex to the next: 0 is packed (12), else >= 12 */
    uint32_t vertex_count;     /* vertices readable at positions */
    const uint32_t *indices;   /* 3 vertex indices a triangle; NULL: triangle i is 3i, 3i+1, 3i+2 */
    uint32_t triangle_count;
} kdrt_triangles;

typedef struct kdrt_ray {
    float org[3];
    float tmin;
    float dir[3];
    float tmax;
    /* Where the walk may start (START CELLS): a cell of the tree that holds org, from
       kdrt_hit.cell, kdrt_spawn_ray() or kdrt_locate(); 0 starts at the root. Only a hint: a
       wrong, stale or foreign cell costs time, never an answer. */
    uint32_t cell;
} kdrt_ray;

typedef struct kdrt_hit {
    float t;
    float u, v;        /* barycentrics of vertices 1 and 2 */
    uint32_t triangle; /* index into the caller's triangles, KDRT_INVALID_ID on a miss */
    /* Scene queries (SCENES): the ID of the geometry hit, a mesh's or, through an instance, the
       instance's; and the instance's ID, or KDRT_INVALID_ID for a hit on a mesh of the scene
       itself. One-tree queries: 0 and KDRT_INVALID_ID. */
    uint32_t geometry;
    uint32_t instance;
    /* The cell (a leaf of the tree, by node index) that holds the hit point, for the next ray's
       start (START CELLS); 0 on a miss, through an instance, and in kdrt_intersect_k's lists. */
    uint32_t cell;
} kdrt_hit;

/* Allocation hooks; user is passed back to both. All zero: KDRT_MALLOC / KDRT_FREE.
   alloc must return memory aligned as malloc's, or NULL. */
typedef struct kdrt_allocator {
    void *(*alloc)(void *user, size_t size);
    void (*free)(void *user, void *ptr);
    void *user;
} kdrt_allocator;

/* A parallel build's hook into the caller's threads (a game engine's job system, a thread pool):
   run() calls task(data, i) once for every i in [0, count), on any threads and in any order, and
   returns when all have finished. The tree does not depend on it (see THE TREE). */
typedef void (*kdrt_task_fn)(void *data, uint32_t index);
typedef struct kdrt_scheduler {
    void (*run)(void *user, kdrt_task_fn task, void *data, uint32_t count);
    void *user;
} kdrt_scheduler;

typedef enum kdrt_builder {
    KDRT_BUILDER_DEFAULT = 0, /* the best builder available: currently KDRT_BUILDER_SAH */
    KDRT_BUILDER_MEDIAN = 1,  /* the original's median-centroid kd-tree (see THE TREE) */
    KDRT_BUILDER_SAH = 2      /* surface area heuristic with perfect splits (see THE TREE) */
} kdrt_builder;

/* How much time KDRT_BUILDER_SAH spends for a better tree (THE TREE). */
typedef enum kdrt_build_quality {
    KDRT_BUILD_QUALITY_DEFAULT = 0, /* KDRT_BUILD_QUALITY_MEDIUM */
    KDRT_BUILD_QUALITY_FAST = 1,    /* binned everywhere, triangles split by their boxes */
    KDRT_BUILD_QUALITY_MEDIUM = 2,  /* binned above KDRT_SAH_EXACT_MAX references, exact below */
    KDRT_BUILD_QUALITY_HIGH = 3     /* every candidate plane at every node (Wald & Havran) */
} kdrt_build_quality;

typedef enum kdrt_intersector {
    KDRT_INTERSECTOR_DEFAULT = 0,    /* KDRT_INTERSECTOR_WATERTIGHT */
    KDRT_INTERSECTOR_WATERTIGHT = 1, /* Woop, Benthin & Wald 2013: no ray slips between triangles
                                        that share an edge or a vertex (QUERIES AND GUARANTEES) */
    KDRT_INTERSECTOR_FAST = 2        /* Moeller & Trumbore 1997: rays through shared edges and
                                        vertices may pass between the triangles */
} kdrt_intersector;

typedef enum kdrt_build_flags {
    /* Leave out triangles with a NaN or infinite coordinate or an index out of range, and count
       them in kdrt_build_report.skipped_triangles, instead of failing the build. */
    KDRT_BUILD_SKIP_INVALID_TRIANGLES = 1u << 0,
    /* Trace this tree with the scalar kernel even where the CPU has AVX2, and build it without
       SSE2 or AVX2 (KERNELS): the tree and the answers are the same bit for bit, so this is for comparing the
       SIMD and scalar code and measuring them. */
    KDRT_BUILD_SCALAR_KERNEL = 1u << 1,
    /* Trace this tree with the AVX2 kernel even where the CPU has AVX-512 (a batch's packets
       then hold 8 rays, not 16): the answers are the same bit for bit; for comparing the two. */
    KDRT_BUILD_AVX2_KERNEL = 1u << 2,
    /* kdrt_tree_load() and kdrt_scene_load() (SAVED TREES): where the bytes are 64-byte aligned
       and the host little-endian (x86-64, aarch64, wasm), the tree uses them where they lie
       instead of copying them: the bytes must then stay alive and unchanged until the tree (or
       scene) is freed. Elsewhere the load copies, as without the flag. Builds refuse it
       (KDRT_ERROR_INVALID_OPTION). */
    KDRT_LOAD_IN_PLACE = 1u << 3
} kdrt_build_flags;

/* The code that runs a tree's queries, chosen when it is built (KERNELS). */
typedef enum kdrt_kernel {
    KDRT_KERNEL_SCALAR = 0, /* portable C */
    KDRT_KERNEL_AVX2 = 1,   /* x86-64 with AVX2: a leaf's triangles tested 8 at a time, a
                               batch's rays walked in packets of 8 */
    KDRT_KERNEL_AVX512 = 2, /* x86-64 with AVX-512: the AVX2 kernel's leaf tests, and a batch's
                               rays walked in packets of 16 */
    KDRT_KERNEL_NEON = 3,   /* aarch64 (NEON): a leaf's triangles tested 4 at a time, a batch's
                               rays walked one by one */
    KDRT_KERNEL_SIMD128 = 4 /* WebAssembly built with SIMD128 (emcc -msimd128): as NEON */
} kdrt_kernel;

/* Start from kdrt_default_build_options(). A zero field means its default, except
   max_leaf_size, where 0 keeps the original's meaning: no tree. */
typedef struct kdrt_build_options {
    kdrt_builder builder;
    kdrt_build_quality quality;   /* KDRT_BUILDER_SAH's: build time against tree quality */
    kdrt_intersector intersector; /* the ray/triangle test every query on this tree uses */
    uint32_t max_leaf_size;   /* a node with at most this many triangles is a leaf; 0: no tree */
    uint32_t max_depth;       /* 0: 8 + 1.3 log2(triangles) (pbrt); clamped to KDRT_MAX_DEPTH */
    uint32_t flags;           /* kdrt_build_flags */
    kdrt_allocator allocator; /* all zero: KDRT_MALLOC / KDRT_FREE */
    /* KDRT_BUILDER_SAH's cost model (0: default): a split costs traversal_cost plus
       intersection_cost times the expected block tests of the children (a leaf of n triangles is
       ceil(n / 8) blocks: THE TREE), scaled by 1 - empty_bonus when one side is empty; a node is
       a leaf unless a split is cheaper than intersection_cost times its blocks. Only the ratio
       of the two costs matters. */
    float sah_traversal_cost;    /* default KDRT_DEFAULT_SAH_TRAVERSAL_COST */
    float sah_intersection_cost; /* default KDRT_DEFAULT_SAH_INTERSECTION_COST */
    float sah_empty_bonus;       /* in [0, 1); default KDRT_DEFAULT_SAH_EMPTY_BONUS */
    /* KDRT_BUILDER_SAH's subtrees run as tasks on this (all zero: one after the other on the
       calling thread). Tasks call allocator.alloc and .free from the scheduler's threads. */
    kdrt_scheduler scheduler;
} kdrt_build_options;

#define KDRT_DEFAULT_MAX_LEAF_SIZE 4
/* The SAH costs a zero option stands for, chosen by measurement: K_T / K_I = 1.5 (K_I a block
   test), with an empty bonus of 0.1 (bench/README.md, "Leaf blocks"). */
#define KDRT_DEFAULT_SAH_TRAVERSAL_COST 30.0f
#define KDRT_DEFAULT_SAH_INTERSECTION_COST 20.0f
#define KDRT_DEFAULT_SAH_EMPTY_BONUS 0.1f

/* What a build found in the input; filled on success and on failure. */
typedef struct kdrt_build_report {
    uint32_t invalid_triangle;  /* first triangle that failed the checks, or KDRT_INVALID_ID */
    uint32_t invalid_geometry;  /* kdrt_scene_build(): the ID of the geometry at fault (a mesh
                                   holding invalid_triangle, a bad instance or ID), else
                                   KDRT_INVALID_ID; kdrt_tree_build(): KDRT_INVALID_ID */
    uint32_t skipped_triangles; /* triangles left out under KDRT_BUILD_SKIP_INVALID_TRIANGLES */
    uint32_t degenerate_triangles; /* zero-area triangles, left out because no ray can hit them */
} kdrt_build_report;

typedef struct kdrt_tree_stats {
    uint32_t triangles;     /* triangles in the tree (skipped and zero-area ones excluded) */
    uint32_t nodes;         /* inner nodes and leaves */
    uint32_t leaves;
    uint32_t max_depth;     /* depth of the deepest leaf; the root is depth 0 */
    uint64_t triangle_refs; /* references stored in leaves: triangles counted once per leaf */
    uint32_t blocks;        /* leaf blocks: a leaf's triangles, 8 to a block (KERNELS) */
    kdrt_kernel kernel;     /* the kernel its queries run */
    size_t bytes;           /* memory the tree owns */
    /* The tree's SAH cost (Wald & Havran 2006; pbrt-v3), in the units of the sah_*_cost options
       the build used (their defaults where 0), whatever the builder: the sum over inner nodes of
       sah_traversal_cost * area(node) / area(root), plus the sum over leaves of
       sah_intersection_cost * blocks(leaf) * area(leaf) / area(root), with blocks(leaf) =
       ceil(triangles(leaf) / 8) and area the surface area of the node's box (the tree's bounds
       cut by its ancestors' splits). The expected cost of a ray through the root box under the
       SAH's assumptions; the empty bonus is not part of it. No tree (max_leaf_size 0):
       sah_intersection_cost * ceil(triangles / 8). Empty tree: 0. */
    double sah_cost;
} kdrt_tree_stats;

typedef struct kdrt_tree kdrt_tree;

/* "MAJOR.MINOR.PATCH": the KDRT_VERSION_STRING the implementation was compiled with. */
KDRT_API const char *kdrt_version(void);
KDRT_API const char *kdrt_result_string(kdrt_result result);
/* A kernel's short name: "scalar", "avx2", "avx512", "neon", "simd128" (kdrt-bench's --kernel
   names); "unknown" for another value. */
KDRT_API const char *kdrt_kernel_string(kdrt_kernel kernel);

KDRT_API kdrt_aabb kdrt_aabb_empty(void);
KDRT_API void kdrt_aabb_grow(kdrt_aabb *box, const float point[3]);
KDRT_API kdrt_aabb kdrt_aabb_union(kdrt_aabb a, kdrt_aabb b);
/* Box of every vertex of every triangle; fails as kdrt_tree_build() does on bad input
   (report may be NULL). An empty mesh gives kdrt_aabb_empty(). */
KDRT_API kdrt_result kdrt_aabb_of_triangles(const kdrt_triangles *mesh, kdrt_aabb *out_box,
                                            kdrt_build_report *report);
/* 1 when the ray's range [max(tmin, 0), tmax] meets the closed box; the overlap goes to
   *t_enter and *t_exit (either may be NULL), each widened by a bound on its rounding error, so
   that no point of the box is left out. Zero and negative-zero direction components are
   exact: a ray parallel to a slab is inside it when its origin is, boundary included. NaN in the
   ray or the box gives 0. */
KDRT_API int kdrt_aabb_intersect_ray(const kdrt_aabb *box, const kdrt_ray *ray, float *t_enter,
                                     float *t_exit);

KDRT_API kdrt_build_options kdrt_default_build_options(void);
/* Builds a tree over mesh. options NULL means defaults; report may be NULL. On failure *out_tree
   is NULL and nothing stays allocated. */
KDRT_API kdrt_result kdrt_tree_build(const kdrt_triangles *mesh, const kdrt_build_options *options,
                                     kdrt_tree **out_tree, kdrt_build_report *report);
KDRT_API void kdrt_tree_free(kdrt_tree *tree); /* NULL is fine */
KDRT_API void kdrt_tree_get_stats(const kdrt_tree *tree, kdrt_tree_stats *out_stats);
/* Inspection: walk a built tree without its internals (tools, debugging, visualisation).
   Nodes are numbered 0 (the root) to kdrt_tree_node_count() - 1 in depth-first order, the below
   child first: an inner node's below child is index + 1 and its whole subtree comes before its
   above child. Triangles reach a node's subtree only through its leaves, so the triangles of a
   subtree are those its leaves refer to. A tree with no tree (max_leaf_size 0) or no triangles is
   one leaf. kdrt_tree_node() finds a node's box and depth by descending from the root: O(depth). */
typedef struct kdrt_node_info {
    int is_leaf;              /* 1 for a leaf, 0 for an inner node */
    int axis;                 /* inner node: split axis, 0 x, 1 y, 2 z; leaf: -1 */
    float split;              /* inner node: plane position on axis; leaf: 0 */
    uint32_t below;           /* inner node: low side child (index + 1); leaf: KDRT_INVALID_ID */
    uint32_t above;           /* inner node: child on the high side; leaf: KDRT_INVALID_ID */
    uint32_t depth;           /* the root is depth 0 */
    kdrt_aabb bounds;         /* kdrt_tree_bounds() cut by the ancestors' splits (as in sah_cost) */
    uint32_t triangle_count;  /* leaf: how many triangles it refers to; inner node: 0 */
    uint32_t first_reference; /* leaf: its references are first_reference .. + triangle_count - 1 */
    /* Leaf: its ropes (START CELLS), [2 * axis + 0] across the face at bounds.min[axis] and
       [2 * axis + 1] across bounds.max[axis]: the smallest node whose box covers that face, or
       KDRT_INVALID_ID on the tree's boundary. Inner node: KDRT_INVALID_ID. */
    uint32_t ropes[6];
} kdrt_node_info;
/* Nodes in the tree (kdrt_tree_stats.nodes); NULL gives 0. */
KDRT_API uint32_t kdrt_tree_node_count(const kdrt_tree *tree);
/* Describes node index. KDRT_ERROR_NULL_ARGUMENT for a NULL tree or out_info,
   KDRT_ERROR_INDEX_OUT_OF_RANGE for index >= kdrt_tree_node_count(); *out_info is then
   untouched. */
KDRT_API kdrt_result kdrt_tree_node(const kdrt_tree *tree, uint32_t index,
                                    kdrt_node_info *out_info);
/* The caller's triangle index (as in kdrt_hit.triangle) that leaf reference number reference refers
   to, for reference < kdrt_tree_stats.triangle_refs; errors as kdrt_tree_node(). */
KDRT_API kdrt_result kdrt_tree_reference(const kdrt_tree *tree, uint32_t reference,
                                         uint32_t *out_triangle);
KDRT_API kdrt_aabb kdrt_tree_bounds(const kdrt_tree *tree);

/* Nearest hit in the ray's range: returns 1 and fills *hit, or returns 0 with
   hit->triangle = KDRT_INVALID_ID (the other fields are then unspecified). NULL arguments
   give 0. */
KDRT_API int kdrt_intersect(const kdrt_tree *tree, const kdrt_ray *ray, kdrt_hit *hit);
/* 1 when any triangle is hit in the ray's range (shadow rays). */
KDRT_API int kdrt_occluded(const kdrt_tree *tree, const kdrt_ray *ray);

/* A query's rules for which hits count: faces culled, and a filter the caller decides with (alpha
   testing, skipping the surface a ray leaves, one-sided glass). Start from kdrt_default_query(),
   which counts every hit. */
typedef enum kdrt_query_flags {
    /* A triangle's front is the side its normal (p1 - p0) x (p2 - p0) points to (the side from
       which its corners run counterclockwise): a ray with dir . normal < 0 hits the front. */
    KDRT_QUERY_CULL_BACK_FACES = 1u << 0,  /* hits on back faces do not count */
    KDRT_QUERY_CULL_FRONT_FACES = 1u << 1  /* hits on front faces do not count */
} kdrt_query_flags;

/* Asked of each candidate hit (ray as the caller gave it, candidate's t, u, v, triangle) before
   it is taken: nonzero to take it, 0 to go on as if the triangle were not there. It may be called
   for a triangle more than once and in any order, and only for candidates nearer than the hits
   taken so far: it must answer the same for the same candidate, and it runs on the querying
   thread. It may run other queries of its own, on this tree or scene or any other (a query
   changes nothing it walks); it must not free, rebuild, move or commit what is being queried
   (kdrt_tree_free(), kdrt_scene_set_transform(), kdrt_scene_commit(), ...), nor change the
   mesh buffers, and it must return: kdrt does not unwind a longjmp or a C++ exception through
   its frames (they hold nothing to release, but the query's answer is then undefined). */
typedef int (*kdrt_filter_fn)(void *user, const kdrt_ray *ray, const kdrt_hit *candidate);

typedef struct kdrt_query {
    uint32_t flags;        /* kdrt_query_flags; other bits are reserved, 0 */
    uint32_t mask;         /* the ray's: a scene's geometry counts only where (its mask & mask)
                              != 0 (SCENES); a tree's one mesh has every bit. kdrt_default_query()
                              sets every bit; 0 hits nothing */
    kdrt_filter_fn filter; /* NULL: every hit that is not culled counts */
    void *user;            /* passed to filter */
} kdrt_query;

KDRT_API kdrt_query kdrt_default_query(void);
/* kdrt_intersect() and kdrt_occluded() counting only the hits query lets through (NULL: all);
   equal t still goes to the lower triangle, among the hits that count. */
KDRT_API int kdrt_intersect_query(const kdrt_tree *tree, const kdrt_ray *ray,
                                  const kdrt_query *query, kdrt_hit *hit);
KDRT_API int kdrt_occluded_query(const kdrt_tree *tree, const kdrt_ray *ray,
                                 const kdrt_query *query);
/* The k nearest hits in the ray's range that query lets through (NULL: all), k = capacity at
   most, into hits[0..k) sorted by t (equal t: the lower triangle first, as kdrt_intersect decides
   ties); returns how many. Each triangle once, with the t, u, v kdrt_intersect would give it;
   exact: no hit nearer than the last one returned is left out. For shadow rays through glass,
   transparency, and counting the surfaces a segment crosses. NULL tree, ray or hits, or capacity
   0, give 0. */
KDRT_API uint32_t kdrt_intersect_k(const kdrt_tree *tree, const kdrt_ray *ray,
                                   const kdrt_query *query, kdrt_hit *hits, uint32_t capacity);

/* rays[0 .. count) traced as kdrt_intersect_query() / kdrt_occluded_query() trace each, hits[i]
   or occluded[i] (1 or 0) its answer, bit for bit; returns how many hit. Neighbouring rays walk
   the tree together in packets of 8 where they can (BATCHES). A NULL tree or rays: every answer
   a miss; NULL hits or occluded: 0, nothing written. */
KDRT_API uint32_t kdrt_intersect_batch(const kdrt_tree *tree, const kdrt_ray *rays,
                                       uint32_t count, const kdrt_query *query, kdrt_hit *hits);
KDRT_API uint32_t kdrt_occluded_batch(const kdrt_tree *tree, const kdrt_ray *rays,
                                      uint32_t count, const kdrt_query *query, uint8_t *occluded);

/* The work one query did, for measuring. Counting is compiled in only
   where KDRT_TRAVERSAL_STATS is defined before the implementation; kdrt_intersect_counted()
   exists only there, and kdrt_intersect() stays free of it. */
typedef struct kdrt_traversal_stats {
    uint64_t inner_nodes;    /* inner nodes visited */
    uint64_t leaves;         /* leaves visited, empty ones included */
    uint64_t empty_leaves;
    uint64_t triangle_tests; /* triangles tested (the scalar kernel's mailbox skips repeats) */
    uint64_t block_tests;    /* 8-triangle block tests (the AVX2 kernel) */
    uint64_t rope_steps;     /* cells left through a face to the next (START CELLS) */
    uint64_t rope_nodes;     /* inner nodes passed going down from a rope to the next cell */
    uint64_t restarts;       /* rope walks handed to the walk from the root (an edge, a corner) */
    /* Batches (BATCHES), the packets' shared work; the rays that go alone count above. */
    uint64_t packets;          /* packets that walked */
    uint64_t packet_lanes;     /* their rays */
    uint64_t packet_steps;     /* inner nodes the packets visited */
    uint64_t packet_step_lanes; /* lanes walking at those steps, added up */
    uint64_t packet_leaves;    /* leaves the packets visited, empty ones included */
    uint64_t packet_blocks;    /* blocks culled for a packet */
    uint64_t packet_triangles; /* triangles the cull left, each tested against a packet's lanes */
} kdrt_traversal_stats;
#ifdef KDRT_TRAVERSAL_STATS
/* kdrt_intersect(), adding its work to *stats (which may be NULL). */
KDRT_API int kdrt_intersect_counted(const kdrt_tree *tree, const kdrt_ray *ray, kdrt_hit *hit,
                                    kdrt_traversal_stats *stats);
/* kdrt_intersect_batch() and kdrt_occluded_batch() with a NULL query, adding their work. */
KDRT_API uint32_t kdrt_intersect_batch_counted(const kdrt_tree *tree, const kdrt_ray *rays,
                                               uint32_t count, kdrt_hit *hits,
                                               kdrt_traversal_stats *stats);
KDRT_API uint32_t kdrt_occluded_batch_counted(const kdrt_tree *tree, const kdrt_ray *rays,
                                              uint32_t count, uint8_t *occluded,
                                              kdrt_traversal_stats *stats);
#endif

/* Where a hit lies: the point from its barycentrics (more accurate than org + t * dir, whose
   error grows with t) and the unit geometric normal, (p1 - p0) x (p2 - p0) normalised, so it faces
   the side from which the corners run counter-clockwise. Either output may be NULL. Returns 0 and
   writes nothing when hit is not a hit on this tree's triangles. The point lies within the
   triangle's bounding box. Reads the caller's buffers. */
KDRT_API int kdrt_hit_surface(const kdrt_tree *tree, const kdrt_hit *hit, float point[3],
                              float normal[3]);
/* Moves a surface point off its surface, along the geometric normal towards the side dir points
   to, by a distance that scales with the point's magnitude (Waechter & Binder, "A Fast and Robust
   Method for Avoiding Self-Intersection", Ray Tracing Gems 2019): 256 ulps of each coordinate, or
   2^-16 near the origin. A ray from the result in direction dir cannot hit the surface it starts
   on, near the origin or far from it; no fixed epsilon involved. normal need not be unit length. */
KDRT_API void kdrt_offset_ray_origin(const float point[3], const float normal[3],
                                     const float dir[3], float out[3]);
/* A secondary ray leaving a hit in direction dir (reflection, refraction, shadow or bounce):
   origin = the hit's surface point offset by kdrt_offset_ray_origin(), tmin = 0,
   tmax = infinity, cell = the start cell that holds the origin (START CELLS). Returns 0 (and a
   ray that misses everything) when hit is not a hit of tree. For a shadow ray to a point q, set
   dir = q - out->org afterwards and keep tmax below 1; the cell stays right. */
KDRT_API int kdrt_spawn_ray(const kdrt_tree *tree, const kdrt_hit *hit, const float dir[3],
                            kdrt_ray *out);
/* The cell that holds point, for kdrt_ray.cell: a camera, a light or an eye inside the scene
   whose rays then share one descent (START CELLS). 0 for a point outside the tree's box, NaN or
   infinite, or a NULL argument. */
KDRT_API uint32_t kdrt_locate(const kdrt_tree *tree, const float point[3]);

/* ==== saved trees (see SAVED TREES): a tree baked once, loaded without a build ==== */

/* Receives a saved tree's bytes, in order, a piece at a time (size > 0): a file, a buffer, an
   engine's archive. Returns nonzero when it took the whole piece, 0 to stop the save. */
typedef int (*kdrt_write_fn)(void *user, const void *bytes, size_t size);

/* The exact number of bytes kdrt_tree_save() writes for tree (0 for NULL). */
KDRT_API size_t kdrt_tree_saved_size(const kdrt_tree *tree);
/* Writes tree through write (SAVED TREES): the same bytes on every run, kernel and platform for
   the same tree. Reads the tree's mesh buffers (their hash goes into the file). Errors:
   KDRT_ERROR_NULL_ARGUMENT, KDRT_ERROR_WRITE_FAILED (write returned 0; what it took so far is
   not a saved tree). */
KDRT_API kdrt_result kdrt_tree_save(const kdrt_tree *tree, kdrt_write_fn write, void *user);
/* A tree from the size bytes kdrt_tree_save() wrote, over mesh: the same mesh buffers, borrowed
   as kdrt_tree_build() borrows them. options (NULL: defaults) gives the allocator and the kernel
   flags (KDRT_BUILD_SCALAR_KERNEL, KDRT_BUILD_AVX2_KERNEL; the kernel is chosen as a build
   chooses it), and KDRT_LOAD_IN_PLACE; the tree's shape and intersector are the file's, the other
   fields are ignored. bytes is only read, and may be freed once the call returns (with
   KDRT_LOAD_IN_PLACE: once the tree is freed). Every field is checked before it
   is used; on failure *out_tree is NULL, nothing stays allocated, and the result says why:
   KDRT_ERROR_NOT_A_SAVED_TREE, KDRT_ERROR_FILE_VERSION, KDRT_ERROR_FILE_BYTE_ORDER,
   KDRT_ERROR_FILE_SIZE, KDRT_ERROR_FILE_CORRUPT, KDRT_ERROR_MESH_MISMATCH (also for a scene's
   file), KDRT_ERROR_OUT_OF_MEMORY, or the mesh view's own errors (KDRT_ERROR_INVALID_STRIDE,
   ...). report (may be NULL) is as a build's with nothing found. */
KDRT_API kdrt_result kdrt_tree_load(const void *bytes, size_t size, const kdrt_triangles *mesh,
                                    const kdrt_build_options *options, kdrt_tree **out_tree,
                                    kdrt_build_report *report);
/* What a saved tree's header says, for tools: read and checked as kdrt_tree_load() reads it
   (magic, byte order, version, checksum, every field in range, the size), the sections and the
   meshes not looked at. */
typedef struct kdrt_saved_tree_info {
    uint32_t version;           /* the format version (KDRT_SAVED_TREE_VERSION) */
    uint64_t size;              /* bytes in the file */
    uint32_t meshes;            /* 1 for kdrt_tree_save(); a scene's meshes (0 or more) */
    uint32_t mesh_triangles;    /* the meshes' triangles, all of them */
    /* The options the tree was built with, as given: builder, quality, intersector,
       max_leaf_size, max_depth, costs, and of the flags KDRT_BUILD_SKIP_INVALID_TRIANGLES only;
       allocator and scheduler zero. */
    kdrt_build_options options;
    uint32_t depth_limit;       /* options.max_depth as the build resolved it */
    kdrt_aabb bounds;           /* kdrt_tree_bounds() */
    kdrt_tree_stats stats;      /* the tree's, but kernel, bytes and sah_cost: 0 (a load's) */
} kdrt_saved_tree_info;
#define KDRT_SAVED_TREE_VERSION 1u
KDRT_API kdrt_result kdrt_saved_tree_read_info(const void *bytes, size_t size,
                                               kdrt_saved_tree_info *out_info);

/* ==== scenes (see SCENES): many meshes and instances behind one query ==== */

typedef enum kdrt_geometry_type {
    KDRT_GEOMETRY_MESH = 0,    /* triangles, built with the scene's other meshes into one tree */
    KDRT_GEOMETRY_INSTANCE = 1 /* a built tree placed in the world by an affine transform */
} kdrt_geometry_type;

typedef enum kdrt_geometry_flags {
    /* In the scene (its ID taken), seen by no query: kdrt_scene_enable() turns it on and off. */
    KDRT_GEOMETRY_DISABLED = 1
} kdrt_geometry_flags;

/* One entry of a scene. Start from kdrt_mesh_geometry() or kdrt_instance_geometry(). */
typedef struct kdrt_geometry {
    kdrt_geometry_type type;
    uint32_t id;   /* the caller's: unique within the scene, not KDRT_INVALID_ID; hits name it */
    uint32_t mask; /* a query sees it only where (mask & kdrt_query.mask) != 0; default all bits */
    void *user;    /* the caller's, handed back by kdrt_scene_geometry() */
    kdrt_triangles mesh;   /* KDRT_GEOMETRY_MESH: borrowed, as by kdrt_tree_build() */
    const kdrt_tree *tree; /* KDRT_GEOMETRY_INSTANCE: borrowed, freed only after the scene */
    /* KDRT_GEOMETRY_INSTANCE: world from object, a 3x4 row-major matrix [R | t]: a point p of
       the tree goes to x_i = R_i0 p_0 + R_i1 p_1 + R_i2 p_2 + t_i, with transform[4 i + j] = R_ij
       and transform[4 i + 3] = t_i. Finite and invertible (|det R| at least 2^-40 times the
       product of its rows' lengths, which is 1 for any rotation and scale): rotations, scales
       (uniform or not), mirrors and shears are all fine. The tree's box carried into the world
       and widened (SCENES) must stay within float's range, below about 3.4e38. */
    float transform[12];
    uint32_t flags; /* kdrt_geometry_flags; 0 by default */
} kdrt_geometry;

typedef struct kdrt_scene kdrt_scene;

/* A mesh entry: id, mesh (copied, its buffers borrowed), every mask bit, no user pointer. */
KDRT_API kdrt_geometry kdrt_mesh_geometry(uint32_t id, const kdrt_triangles *mesh);
/* An instance entry: id, tree (borrowed), transform (NULL: identity), every mask bit. */
KDRT_API kdrt_geometry kdrt_instance_geometry(uint32_t id, const kdrt_tree *tree,
                                              const float transform[12]);
/* Builds a scene over count entries (0 is fine: every ray misses). The meshes are built into one
   tree with options (NULL: defaults); the instances go under a top-level tree over their world
   boxes. On failure *out_scene is NULL, nothing stays allocated, and report (which may be NULL)
   names the geometry at fault: a mesh's bad triangle or view as kdrt_tree_build() would,
   KDRT_ERROR_NULL_ARGUMENT for an instance without a tree, KDRT_ERROR_INVALID_TRANSFORM,
   KDRT_ERROR_INVALID_GEOMETRY_ID for an ID used twice or KDRT_INVALID_ID, KDRT_ERROR_INVALID_OPTION
   for an unknown type or flag. The scene keeps options (its allocator and scheduler serve every
   commit; a mesh tree rebuilt by a commit is built with them). */
KDRT_API kdrt_result kdrt_scene_build(const kdrt_geometry *geometries, uint32_t count,
                                      const kdrt_build_options *options, kdrt_scene **out_scene,
                                      kdrt_build_report *report);
KDRT_API void kdrt_scene_free(kdrt_scene *scene); /* NULL is fine; the borrowed trees stay */
/* Changes to a built scene, each taking effect at the next kdrt_scene_commit(): until then
   queries see the scene as it was. "The scene" below is the scene as it will be after that
   commit, with the changes made so far. None of them may overlap a query on the scene.
   Moves instance id to a new transform. KDRT_ERROR_INVALID_GEOMETRY_ID when id is no instance
   of the scene, KDRT_ERROR_INVALID_TRANSFORM (nothing changes). */
KDRT_API kdrt_result kdrt_scene_set_transform(kdrt_scene *scene, uint32_t id,
                                              const float transform[12]);
/* Adds an entry, checked as kdrt_scene_build() checks it (the same result codes; nothing changes
   on failure): KDRT_ERROR_INVALID_GEOMETRY_ID when its ID is in the scene. An instance costs the
   commit its placing; a mesh makes the commit rebuild the scene's mesh tree. */
KDRT_API kdrt_result kdrt_scene_attach(kdrt_scene *scene, const kdrt_geometry *geometry);
/* Removes entry id (KDRT_ERROR_INVALID_GEOMETRY_ID when there is none); its ID is free again.
   A mesh's removal makes the commit rebuild the mesh tree. */
KDRT_API kdrt_result kdrt_scene_detach(kdrt_scene *scene, uint32_t id);
/* Disables entry id (enabled 0: KDRT_GEOMETRY_DISABLED set) or enables it again (1): a disabled
   entry stays in the scene, its ID taken, and no query sees it. No tree is rebuilt for it. */
KDRT_API kdrt_result kdrt_scene_enable(kdrt_scene *scene, uint32_t id, int enabled);
/* Applies the changes: the instances placed again and the top level rebuilt over their boxes;
   the mesh tree rebuilt only when meshes were attached or detached (with the options of
   kdrt_scene_build(), its scheduler included). A commit with nothing to apply does nothing.
   On failure (KDRT_ERROR_OUT_OF_MEMORY, or a rebuilt mesh tree's error such as
   KDRT_ERROR_NON_FINITE_VERTEX) the scene is as it was before the commit and the changes stay
   pending. */
KDRT_API kdrt_result kdrt_scene_commit(kdrt_scene *scene);
/* The scene's entry with this ID as of the last commit (its transform and flags the committed
   ones), or NULL; valid until the next commit. */
KDRT_API const kdrt_geometry *kdrt_scene_geometry(const kdrt_scene *scene, uint32_t id);
/* The world box of everything in the scene (kdrt_aabb_empty() when it holds no triangle). */
KDRT_API kdrt_aabb kdrt_scene_bounds(const kdrt_scene *scene);

/* The one-tree queries on a scene, query NULL meaning kdrt_default_query(). Equal t goes to the
   lower geometry ID, then the lower triangle index. kdrt_scene_hit_surface() and
   kdrt_scene_spawn_ray() give world-space points and unit normals for hits through instances
   too (the normal transformed by the inverse transpose, so it stays perpendicular under any
   scale or shear; a mirror turns it with the winding). */
KDRT_API int kdrt_scene_intersect(const kdrt_scene *scene, const kdrt_ray *ray,
                                  const kdrt_query *query, kdrt_hit *hit);
KDRT_API int kdrt_scene_occluded(const kdrt_scene *scene, const kdrt_ray *ray,
                                 const kdrt_query *query);
/* kdrt_intersect_batch() and kdrt_occluded_batch() on a scene: each ray answered as
   kdrt_scene_intersect() / kdrt_scene_occluded() answer it. */
KDRT_API uint32_t kdrt_scene_intersect_batch(const kdrt_scene *scene, const kdrt_ray *rays,
                                             uint32_t count, const kdrt_query *query,
                                             kdrt_hit *hits);
KDRT_API uint32_t kdrt_scene_occluded_batch(const kdrt_scene *scene, const kdrt_ray *rays,
                                            uint32_t count, const kdrt_query *query,
                                            uint8_t *occluded);
KDRT_API uint32_t kdrt_scene_intersect_k(const kdrt_scene *scene, const kdrt_ray *ray,
                                         const kdrt_query *query, kdrt_hit *hits,
                                         uint32_t capacity);
KDRT_API int kdrt_scene_hit_surface(const kdrt_scene *scene, const kdrt_hit *hit, float point[3],
                                    float normal[3]);
KDRT_API int kdrt_scene_spawn_ray(const kdrt_scene *scene, const kdrt_hit *hit, const float dir[3],
                                  kdrt_ray *out);
/* kdrt_locate() in the scene's mesh tree, whose walk a ray's cell starts (instances start at
   their root); 0 without meshes. */
KDRT_API uint32_t kdrt_scene_locate(const kdrt_scene *scene, const float point[3]);
/* A baked scene (SCENES, SAVED TREES): the scene's mesh tree, as of the last commit, saved as
   kdrt_tree_save() saves a tree (a scene without meshes saves a file of none), and its size. */
KDRT_API size_t kdrt_scene_saved_size(const kdrt_scene *scene);
KDRT_API kdrt_result kdrt_scene_save_meshes(const kdrt_scene *scene, kdrt_write_fn write,
                                            void *user);
/* kdrt_scene_build() with the mesh tree loaded from bytes (kdrt_scene_save_meshes()'s) instead of
   built: the same entries as when it was saved (the same meshes under the same IDs; their masks,
   flags and user pointers, and the instances, may differ). The scene takes the file's build
   options (builder, quality, intersector, leaf size, depth, costs) for the mesh trees later
   commits rebuild, and from options (NULL: defaults) the allocator, scheduler and kernel flags.
   Errors: kdrt_scene_build()'s for the entries, kdrt_tree_load()'s for the file, with
   KDRT_ERROR_MESH_MISMATCH naming in report->invalid_geometry the first mesh that differs
   (KDRT_INVALID_ID when their number does). */
KDRT_API kdrt_result kdrt_scene_load(const kdrt_geometry *geometries, uint32_t count,
                                     const void *bytes, size_t size,
                                     const kdrt_build_options *options, kdrt_scene **out_scene,
                                     kdrt_build_report *report);

/* ==== closest point and overlap (see CLOSEST POINT AND OVERLAP): beyond rays ==== */

/* The answer of a closest-point query. */
typedef struct kdrt_closest {
    float point[3];    /* the nearest point of the triangle, in the world for a scene */
    float distance;    /* from the query's point to the triangle (see the manual's bound) */
    float u, v;        /* barycentrics of point: (1 - u - v) p0 + u p1 + v p2 */
    uint32_t triangle; /* as kdrt_hit.triangle; KDRT_INVALID_ID when nothing is within reach */
    uint32_t geometry; /* as kdrt_hit.geometry: a scene's entry; 0 for a tree */
    uint32_t instance; /* as kdrt_hit.instance: the instance's ID, or KDRT_INVALID_ID */
} kdrt_closest;

/* A triangle an overlap query found: as kdrt_hit names it. */
typedef struct kdrt_overlap {
    uint32_t triangle; /* index in its mesh (an instance's: in its tree's mesh) */
    uint32_t geometry; /* a scene's entry; 0 for a tree */
    uint32_t instance; /* the instance's ID, or KDRT_INVALID_ID */
} kdrt_overlap;

/* Called once for each triangle an overlap query finds, in no particular order, on the querying
   thread: nonzero to go on, 0 to stop the query there. It may run other queries (on this tree or
   scene too); it must not free, rebuild or change what is queried. */
typedef int (*kdrt_overlap_fn)(void *user, const kdrt_overlap *found);

/* The nearest point of any triangle of tree to point, within max_distance (INFINITY: anywhere;
   0: only triangles through point). Equal distances go to the lower triangle index. Returns
   KDRT_SUCCESS with out->triangle = KDRT_INVALID_ID (and distance INFINITY) when no triangle is
   within max_distance; KDRT_ERROR_NULL_ARGUMENT for a NULL argument, and
   KDRT_ERROR_INVALID_QUERY for a NaN or infinite point or a NaN or negative max_distance
   (out->triangle is then KDRT_INVALID_ID too). Allocates nothing; const tree, any threads. */
KDRT_API kdrt_result kdrt_closest_point(const kdrt_tree *tree, const float point[3],
                                        float max_distance, kdrt_closest *out);
/* Calls callback (when not NULL) once for every triangle of tree that meets the closed box, and
   puts how many that was in *out_count (which may be NULL): the callback's last triangle counts
   when it stops the query. A box with min > max on an axis is empty (0 triangles); a flat box
   (min == max) is a rectangle, a segment or a point; an infinite bound is a half-space.
   KDRT_ERROR_INVALID_QUERY for a NaN bound, KDRT_ERROR_NULL_ARGUMENT for a NULL tree or box. */
KDRT_API kdrt_result kdrt_overlap_box(const kdrt_tree *tree, const kdrt_aabb *box,
                                      kdrt_overlap_fn callback, void *user, uint64_t *out_count);
/* The same for the closed ball of radius (0: the point itself; INFINITY: every triangle) around
   center. KDRT_ERROR_INVALID_QUERY for a NaN or infinite center or a NaN or negative radius. */
KDRT_API kdrt_result kdrt_overlap_sphere(const kdrt_tree *tree, const float center[3],
                                         float radius, kdrt_overlap_fn callback, void *user,
                                         uint64_t *out_count);
/* The three on a scene: every enabled geometry whose mask shares a bit with mask (0xFFFFFFFF:
   all of them), instances included, distances and shapes in the world. Closest point: equal
   distances go to the lower geometry ID, then the lower triangle. */
KDRT_API kdrt_result kdrt_scene_closest_point(const kdrt_scene *scene, const float point[3],
                                              float max_distance, uint32_t mask,
                                              kdrt_closest *out);
KDRT_API kdrt_result kdrt_scene_overlap_box(const kdrt_scene *scene, const kdrt_aabb *box,
                                            uint32_t mask, kdrt_overlap_fn callback, void *user,
                                            uint64_t *out_count);
KDRT_API kdrt_result kdrt_scene_overlap_sphere(const kdrt_scene *scene, const float center[3],
                                               float radius, uint32_t mask,
                                               kdrt_overlap_fn callback, void *user,
                                               uint64_t *out_count);

/* ==== optics (see OPTICS): reflection, refraction, Fresnel reflectance, the medium stack ==== */

/* The mirror direction of incident about the plane with this normal, as a unit vector. Neither
   vector needs unit length; the normal may face either way. A NaN or infinite component or an
   all-zero vector gives out = incident. out may be incident itself. */
KDRT_API void kdrt_reflect(const float incident[3], const float normal[3], float out[3]);
/* Snell's law, eta = eta_incident / eta_transmitted. Returns 1 with the refracted unit direction
   in out; 0 on total internal reflection, with out = kdrt_reflect()'s mirror direction; -1 on
   invalid input (a NaN or infinite component, an all-zero vector, eta not finite and > 0), with
   out = incident (and nothing written if a pointer is NULL). out may be incident itself. */
KDRT_API int kdrt_refract(const float incident[3], const float normal[3], float eta, float out[3]);
/* Exact Fresnel reflectance of a smooth dielectric surface for unpolarised light, the mean of the
   s and p reflectances; 1 on total internal reflection. cos_i is the cosine of the angle of
   incidence (see OPTICS); its magnitude is used, at most 1. eta = 1 gives 0 (no surface), and so
   does invalid input (NaN cos_i, eta not finite and > 0). */
KDRT_API float kdrt_fresnel_dielectric(float cos_i, float eta);
/* The s- and p-polarised reflectances behind kdrt_fresnel_dielectric(); either pointer may be
   NULL. rp is 0 at Brewster's angle, tan(theta_i) = 1 / eta. */
KDRT_API void kdrt_fresnel_dielectric_sp(float cos_i, float eta, float *rs, float *rp);
/* Schlick's approximation R0 + (1 - R0) (1 - cos)^5, R0 = ((eta - 1) / (eta + 1))^2, with cos the
   cosine on the less dense side (cos_t when eta > 1; 1 on total internal reflection). Cheaper,
   and off by up to 0.036 for glass (eta 1.5 or 1/1.5) and 0.060 for water (1.333). Same inputs
   and special cases as kdrt_fresnel_dielectric(). */
KDRT_API float kdrt_fresnel_schlick(float cos_i, float eta);

/* The medium stack (see OPTICS). KDRT_MEDIA_STACK_CAPACITY (at least 1) sizes the struct: define
   it the same in every file. */
#ifndef KDRT_MEDIA_STACK_CAPACITY
#define KDRT_MEDIA_STACK_CAPACITY 16
#endif

typedef struct kdrt_medium {
    uint32_t object; /* the caller's id of the object whose inside this is; KDRT_INVALID_ID would
                        read as "outside" in kdrt_media_current_object() */
    float ior;       /* its index of refraction */
    int priority;    /* higher wins where media overlap; all equal: the original's plain stack */
} kdrt_medium;

/* Plain data: copy it to branch a path. Set it up with kdrt_media_init(). */
typedef struct kdrt_media_stack {
    kdrt_medium media[KDRT_MEDIA_STACK_CAPACITY]; /* in the order entered */
    uint32_t count;
    float outside_ior; /* the medium outside every object: air, 1.000293, or 1 */
} kdrt_media_stack;

/* What happens where a ray meets a surface of an object, from kdrt_media_at_surface(). */
typedef struct kdrt_media_crossing {
    int entering;          /* 1: the object is not in the stack, the ray enters it; 0: it leaves */
    int real;              /* 0: a false surface, which changes no medium: ignore it (see OPTICS) */
    float eta_incident;    /* index of the current medium */
    float eta_transmitted; /* index beyond the surface; eta_incident when the surface is false */
} kdrt_media_crossing;

/* An empty stack in a medium of index outside_ior. Invalid outside_ior: KDRT_ERROR_INVALID_IOR,
   and the stack is still set up, with index 1. */
KDRT_API kdrt_result kdrt_media_init(kdrt_media_stack *stack, float outside_ior);
/* Index of the current medium: the entered one of highest priority, ties to the latest entered,
   or outside_ior. A NULL stack is an empty one with outside index 1. */
KDRT_API float kdrt_media_current_ior(const kdrt_media_stack *stack);
/* Object of the current medium, or KDRT_INVALID_ID outside every object (or for NULL). */
KDRT_API uint32_t kdrt_media_current_object(const kdrt_media_stack *stack);
KDRT_API int kdrt_media_contains(const kdrt_media_stack *stack, uint32_t object);
/* Pushes object. KDRT_ERROR_MEDIA_STACK_FULL, KDRT_ERROR_INVALID_IOR or
   KDRT_ERROR_NULL_ARGUMENT leave the stack as it was. An object entered twice is held twice. */
KDRT_API kdrt_result kdrt_media_enter(kdrt_media_stack *stack, uint32_t object, float ior,
                                      int priority);
/* Removes object's latest entry wherever it is (media may overlap); the others keep their order.
   KDRT_ERROR_NOT_IN_MEDIUM or KDRT_ERROR_NULL_ARGUMENT leave the stack as it was. */
KDRT_API kdrt_result kdrt_media_leave(kdrt_media_stack *stack, uint32_t object);
/* Classifies a surface of object hit by a ray with this stack. ior and priority are the
   object's, used when the ray enters it (when it leaves, the stack's entry counts). Changes
   nothing. A NULL stack is an empty one with outside index 1. */
KDRT_API kdrt_media_crossing kdrt_media_at_surface(const kdrt_media_stack *stack, uint32_t object,
                                                   float ior, int priority);

#ifdef __cplusplus
}
#endif
#endif /* KDRT_H */

/* ============================================================================================ */
/*                                        IMPLEMENTATION                                        */
/* ============================================================================================ */
#if defined(KDRT_IMPLEMENTATION) && !defined(KDRT__IMPLEMENTED)
#define KDRT__IMPLEMENTED

/* The implementation includes this file again to compile its packet code for each vector width
   (PACKETS): the name it is included by, beside the file that includes it. */
#ifndef KDRT_HEADER_FILENAME
#define KDRT_HEADER_FILENAME "kdrt.h"
#endif

/* ==== configuration: libc, KDRT_ASSERT, KDRT_MALLOC / KDRT_FREE ==== */

#include <math.h>   /* INFINITY; sqrt, fma and fabs (libm) */
#include <stdlib.h> /* qsort, and malloc/free unless KDRT_MALLOC is defined */
#include <string.h>
/* The exact tests and the walk's NaN checks (t != t) need IEEE arithmetic, which -ffast-math and
   -ffinite-math-only (MSVC: /fp:fast) let the compiler fold away: rays with NaN hit, and the
   kernels disagreed. So the implementation refuses them (the input checks are bit tests and
   would survive); the files that only include the header are free to use them. */
#if defined(__FAST_MATH__) || (defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__) ||           \
    defined(_M_FP_FAST)
#error "kdrt: compile the file that defines KDRT_IMPLEMENTATION without -ffast-math, -ffinite-math-only or /fp:fast: its NaN and infinity checks and its exact tests need IEEE arithmetic (the files that only include kdrt.h may keep them)"
#endif

/* The same answers on every platform: each operation rounds once, as written. A compiler that
   fuses a * b + c into one FMA (GCC in its GNU modes, which CMake's defaults are; Clang wherever
   the target has FMA, -march=haswell or aarch64; MSVC's /fp:contract) changes the last bits of t,
   u and v, and the kernels would disagree between machines. So contraction is off for the
   implementation, whatever the command line says, and restored after it. Clang alone ignores
   these pragmas under an explicit -ffp-contract=fast: do not give it that for this file. */
#if defined(__clang__)
/* Clang 14 supports float_control only where the target has strict FP (x86, not aarch64 or
   wasm): elsewhere its push and pop are ignored, quietly, and contract(off) holds to the end of
   the file. */
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wignored-pragmas"
#pragma float_control(push)
#pragma clang diagnostic pop
#pragma clang fp contract(off)
#elif defined(__GNUC__)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

/* x87 arithmetic (i386 without SSE2) keeps intermediates in 80 bits and rounds them when it
   spills them: its answers differ from every other platform's, and from run to run of the
   optimiser's choices. Refused: float and double must be evaluated in their own precision
   (FLT_EVAL_METHOD 0, or 16 where the CPU has half floats). */
#include <float.h>
#if (defined(FLT_EVAL_METHOD) && (FLT_EVAL_METHOD == 1 || FLT_EVAL_METHOD == 2)) ||               \
    (defined(_M_IX86) && (!defined(_M_IX86_FP) || _M_IX86_FP < 2))
#error "kdrt: compile the file that defines KDRT_IMPLEMENTATION with SSE2 arithmetic (GCC and Clang: -msse2 -mfpmath=sse; MSVC: /arch:SSE2): x87's 80-bit intermediates give other answers than every other platform's"
#endif

/* SSE2, part of x86-64 itself: the builder's binning (kdrt__bin_refs), with no target attribute.
   MSVC defines no __SSE2__ on x64 (ARM64EC defines _M_X64 too, but emulates x64 code). */
#if !defined(KDRT_NO_SIMD) &&                                                                      \
    (defined(__SSE2__) || (defined(_M_X64) && !defined(_M_ARM64EC)))
#define KDRT__SSE2 1
#include <emmintrin.h>
#endif

/* One at most, by the target: the AVX2 kernel (and the AVX-512 one) on x86-64 with GCC, Clang,
   clang-cl or MSVC (not ARM64EC, which emulates x64 code), the 4-wide kernel on aarch64 and on
   WebAssembly with SIMD128; none under KDRT_NO_SIMD, and on x86-64 none under KDRT_NO_AVX2
   (KERNELS, PLATFORMS). */
#if !defined(KDRT_NO_SIMD) && !defined(KDRT_NO_AVX2) &&                                            \
    ((defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))) ||                        \
     (defined(_MSC_VER) && defined(_M_X64) && !defined(_M_ARM64EC)))
#define KDRT__AVX2 1
#elif !defined(KDRT_NO_SIMD) && (defined(__GNUC__) || defined(__clang__)) &&                       \
    (defined(__aarch64__) || defined(__wasm_simd128__))
#define KDRT__X4 1
#endif

#if defined(KDRT__AVX2)
#include <immintrin.h>
#if defined(_MSC_VER) && !defined(__clang__)
/* cl.exe names each function with AVX code compiled without /arch:AVX (C4752): kdrt's run
   only where the CPU check found AVX2. Popped at the end of the implementation. */
#pragma warning(push)
#pragma warning(disable : 4752)
#endif
#if defined(__GNUC__) || defined(__clang__)
#define KDRT__TARGET_AVX2 __attribute__((target("avx2")))
/* The closest-point walk's (CLOSEST POINT AND OVERLAP): fma() one instruction. */
#define KDRT__TARGET_AVX2_FMA __attribute__((target("avx2,fma")))
/* The AVX-512 kernel: the AVX2 kernel, and a batch's packets 16 rays wide (BATCHES). */
#define KDRT__TARGET_AVX512 __attribute__((target("avx2,avx512f")))
#else
#define KDRT__TARGET_AVX2
#define KDRT__TARGET_AVX2_FMA
#define KDRT__TARGET_AVX512
#endif
#if defined(_MSC_VER) && defined(__clang__)
/* clang-cl's immintrin.h, unlike MSVC's, declares only the intrinsics the command line enables
   (/arch): those of the target attributes are named here (SSE4.1's for _MM_FROUND_*). */
#include <smmintrin.h>
#include <avxintrin.h>
#include <avx2intrin.h>
#include <fmaintrin.h>
#include <avx512fintrin.h>
#endif

#if defined(_MSC_VER)
#include <intrin.h> /* __cpuid, __cpuidex, _BitScanForward */
/* What __builtin_cpu_supports asks, from cpuid and xgetbv, with nothing beyond the CRT (clang-cl's
   __builtin_cpu_supports needs compiler-rt, which MSVC links lack): 2 where the CPU has AVX2 and
   AVX512F and the OS saves the ZMM registers, 1 where it has AVX2 and the OS saves the YMM ones,
   else 0. */
#if defined(__clang__)
__attribute__((target("xsave")))
#endif
static int kdrt__cpu_vector_level(void)
{
    const unsigned osxsave_and_avx = 1u << 27 | 1u << 28; /* cpuid 1, ecx */
    const unsigned avx2 = 1u << 5, avx512f = 1u << 16;    /* cpuid 7, ebx */
    int info[4];
    unsigned long long xcr0;
    __cpuid(info, 0);
    if (info[0] < 7) return 0;
    __cpuid(info, 1);
    if (((unsigned)info[2] & osxsave_and_avx) != osxsave_and_avx) return 0;
    xcr0 = _xgetbv(0);
    if ((xcr0 & 0x6u) != 0x6u) return 0; /* XCR0 bits 1, 2: the XMM and YMM registers */
    __cpuidex(info, 7, 0);
    if (!((unsigned)info[1] & avx2)) return 0;
    /* bits 5, 6, 7: the mask registers, the ZMM registers' upper halves, ZMM16 to ZMM31 */
    return ((unsigned)info[1] & avx512f) && (xcr0 & 0xE0u) == 0xE0u ? 2 : 1;
}

static int kdrt__cpu_has_avx2(void) { return kdrt__cpu_vector_level() >= 1; }
static int kdrt__cpu_has_avx512(void) { return kdrt__cpu_vector_level() >= 2; }
static int kdrt__cpu_has_fma(void)
{
    int info[4];
    __cpuid(info, 1);
    return ((unsigned)info[2] >> 12) & 1u; /* cpuid 1, ecx bit 12 */
}
#else
static int kdrt__cpu_has_avx2(void)
{
    __builtin_cpu_init(); /* idempotent; needed when called before constructors have run */
    return __builtin_cpu_supports("avx2") != 0;
}

static int kdrt__cpu_has_avx512(void)
{
    __builtin_cpu_init(); /* also checks that the OS saves the AVX-512 registers */
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("avx512f");
}

static int kdrt__cpu_has_fma(void)
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("fma") != 0;
}
#endif

#else
static int kdrt__cpu_has_avx2(void) { return 0; }
static int kdrt__cpu_has_avx512(void) { return 0; }
static int kdrt__cpu_has_fma(void) { return 0; }
#endif

#ifndef KDRT_ASSERT
#include <assert.h>
#define KDRT_ASSERT(x) assert(x)
#endif

#if defined(KDRT_MALLOC) != defined(KDRT_FREE)
#error "kdrt: define both KDRT_MALLOC and KDRT_FREE, or neither"
#endif
#ifndef KDRT_MALLOC
#define KDRT_MALLOC(size, user) ((void)(user), malloc(size))
#define KDRT_FREE(ptr, user) ((void)(user), free(ptr))
#endif

/* The SAH builder's two measured choices (see CONFIGURATION). The bins' counts live on the
   stack, 24 bytes a bin. */
#if defined(KDRT__SAH_BINS) || defined(KDRT__SAH_EXACT_MAX)
#error "kdrt: KDRT__SAH_BINS and KDRT__SAH_EXACT_MAX are now KDRT_SAH_BINS and KDRT_SAH_EXACT_MAX"
#endif
#ifndef KDRT_SAH_BINS
#define KDRT_SAH_BINS 256u
#endif
#if KDRT_SAH_BINS < 2 || KDRT_SAH_BINS > 1024
#error "kdrt: KDRT_SAH_BINS must be 2 to 1024"
#endif
/* KDRT_BUILD_QUALITY_FAST's bins: fewer, as it bins every node. */
#define KDRT__FAST_BINS (KDRT_SAH_BINS < 32u ? KDRT_SAH_BINS : 32u)
#ifndef KDRT_SAH_EXACT_MAX
#define KDRT_SAH_EXACT_MAX 128u
#endif
#if KDRT_SAH_EXACT_MAX < 0 || KDRT_SAH_EXACT_MAX > 0xFFFFFFFF
#error "kdrt: KDRT_SAH_EXACT_MAX must be 0 to 4294967295"
#endif
#ifndef KDRT_SAH_REFERENCE_BUDGET
#define KDRT_SAH_REFERENCE_BUDGET 8u
#endif
#if KDRT_SAH_REFERENCE_BUDGET < 1 || KDRT_SAH_REFERENCE_BUDGET > 64
#error "kdrt: KDRT_SAH_REFERENCE_BUDGET must be 1 to 64"
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ==== the tree's layout: nodes, triangle records, the tree ==== */

/* 8-byte node (pbrt-v3's layout). bits: low 2 = axis 0..2, or KDRT__LEAF; high 30 = index of
   the above child (the below child follows its parent), or a leaf's triangle count. Only the
   kdrt__node_* helpers below read or write bits. */
typedef struct kdrt__node {
    union {
        float split;    /* inner node: plane position on its axis */
        uint32_t first; /* leaf: its first entry in the builder's refs; in a built tree, its
                           first block in kdrt_tree.blocks (kdrt__pack_blocks) */
    } u;
    uint32_t bits;
} kdrt__node;

typedef char kdrt__node_is_8_bytes[sizeof(kdrt__node) == 8 ? 1 : -1];

#define KDRT__LEAF 3u /* kdrt__node_axis() of a leaf */

/* A leaf of count references from first_ref on (count < 2^30: KDRT_MAX_TRIANGLES). */
static inline kdrt__node kdrt__node_leaf(uint32_t first_ref, uint32_t count)
{
    kdrt__node n;
    n.u.first = first_ref;
    n.bits = (count << 2) | KDRT__LEAF;
    return n;
}

/* An inner node split at split on axis (0..2); its above child is node above (< 2^30). */
static inline kdrt__node kdrt__node_inner(uint32_t axis, float split, uint32_t above)
{
    kdrt__node n;
    n.u.split = split;
    n.bits = (above << 2) | axis;
    return n;
}

/* The split axis, 0..2, or KDRT__LEAF; an inner node's above child; a leaf's triangle count. */
static inline uint32_t kdrt__node_axis(const kdrt__node *n) { return n->bits & 3u; }
static inline int kdrt__node_is_leaf(const kdrt__node *n)
{
    return kdrt__node_axis(n) == KDRT__LEAF;
}
static inline uint32_t kdrt__node_above(const kdrt__node *n) { return n->bits >> 2; }
static inline uint32_t kdrt__node_count(const kdrt__node *n) { return n->bits >> 2; }

/* A leaf's triangles as the intersection tests read them: 8 to a block, each lane a triangle's
   corners, copied from the caller's buffers, structure of arrays so that the AVX2 kernel loads a
   coordinate of 8 corners at once. Corners, not edges: a corner two triangles share is the same
   floats in both, so both transform it identically (the watertight test needs that). A leaf's
   last block is filled up with copies of its last triangle, which can only repeat its answer. */
#define KDRT__LANES 8u
typedef struct kdrt__block {
    float corner[9][KDRT__LANES]; /* [3 * k + a][lane]: coordinate a of the lane's corner k */
    uint32_t id[KDRT__LANES]; /* the caller's triangle index: kdrt_hit.triangle, and the tie rule */
} kdrt__block;

typedef char kdrt__block_is_5_cache_lines[sizeof(kdrt__block) == 320 ? 1 : -1];

/* KDRT_KERNEL_NEON or KDRT_KERNEL_SIMD128 where the 4-wide kernel is compiled in (no CPU check:
   the target has it), else KDRT_KERNEL_SCALAR. */
static kdrt_kernel kdrt__kernel_x4(void);

/* A leaf as the rope walk sees it (START CELLS): its box, the tree's bounds cut by its ancestors'
   splits, and its ropes, [2 * axis + side] the node across the face at lo[axis] (side 0) or
   hi[axis] (side 1), KDRT__NO_ROPE on the tree's boundary. */
#define KDRT__NO_ROPE 0xFFFFFFFFu
typedef struct kdrt__cell {
    float lo[3], hi[3];
    uint32_t rope[6];
} kdrt__cell;

/* A mesh of a tree. A tree numbers its triangles across its meshes: mesh k's triangle i is
   first + i. kdrt_tree_build() makes one (ID 0); a scene's mesh tree one per mesh geometry, in
   ID order, so that the lower number is the lower (geometry ID, triangle), the tie rule. */
typedef struct kdrt__part {
    kdrt_triangles mesh; /* borrowed; position_stride resolved (never 0) */
    uint32_t first;      /* the tree's number for its triangle 0 */
    uint32_t id, mask;   /* the geometry's */
} kdrt__part;

/* The meshes a tree is built over: parts[0 .. count), triangles in all. */
typedef struct kdrt__meshes {
    const kdrt__part *parts;
    uint32_t count, triangles;
} kdrt__meshes;

struct kdrt_tree {
    kdrt__meshes meshes; /* parts: &one, or a scene's array */
    kdrt__part one;      /* kdrt_tree_build()'s mesh */
    int masks_full;      /* every part's mask has every bit: a ray's mask needs no test */
    int watertight;      /* options.intersector: 1 watertight, 0 fast (Moeller-Trumbore) */
    int simd; /* the kernel: 0 scalar, 1 AVX2, 2 AVX-512, 3 NEON, 4 SIMD128 (kdrt_kernel's) */
    int closest_fma; /* the kernel is AVX2 or AVX-512 and the CPU has FMA: kdrt__closest_walk */
    kdrt_allocator allocator;
    kdrt_aabb bounds;
    kdrt__node *nodes;
    kdrt__block *blocks;  /* the leaves' blocks, leaf by leaf, depth first; 64-byte aligned */
    void *block_memory;   /* what was allocated for blocks */
    uint32_t *block_refs; /* [b]: the reference number of block b's lane 0 (inspection) */
    kdrt__cell *cells;    /* one a leaf, in depth-first order */
    uint32_t *cell_of;    /* [node]: a leaf's index in cells (inner nodes: KDRT__NO_ROPE) */
    kdrt_tree_stats stats;
    /* What shaped it, for a save (SAVED TREES): the build's options as given, with flags only
       KDRT_BUILD_SKIP_INVALID_TRIANGLES and no allocator or scheduler, and max_depth resolved. */
    kdrt_build_options shape;
    uint32_t depth_limit;
    int in_place; /* loaded with KDRT_LOAD_IN_PLACE: the arrays are the caller's bytes */
};

/* ==== small helpers: floats, cross products, allocation ==== */

/* Finite: the exponent bits not all ones (those are NaN and the infinities). A bit test, not a
   float comparison, so no compiler's finite-math assumption can fold it away. */
static int kdrt__finite(float x)
{
    uint32_t bits;
    memcpy(&bits, &x, sizeof bits);
    return (bits & 0x7f800000u) != 0x7f800000u;
}
static float kdrt__abs(float x) { return x < 0.0f ? -x : x; }

/* The next float towards +infinity / -infinity (finite x). */
static float kdrt__next_up(float x)
{
    uint32_t bits;
    if (x == 0.0f) x = 0.0f; /* -0 steps like +0 */
    memcpy(&bits, &x, sizeof bits);
    bits = x >= 0.0f ? bits + 1u : bits - 1u;
    memcpy(&x, &bits, sizeof bits);
    return x;
}
static float kdrt__next_down(float x) { return -kdrt__next_up(-x); }

/* x rounded to a float no greater (up: no smaller). */
static float kdrt__float_down(double x)
{
    float f = (float)x;
    return (double)f > x ? kdrt__next_down(f) : f;
}
static float kdrt__float_up(double x)
{
    float f = (float)x;
    return (double)f < x ? kdrt__next_up(f) : f;
}

/* c = a x b, in the precision of the inputs; c must not be a or b. */
static void kdrt__cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static void kdrt__cross_float(const float a[3], const float b[3], float c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static void *kdrt__alloc(const kdrt_allocator *a, size_t size)
{
    if (size == 0) size = 1;
    return a->alloc ? a->alloc(a->user, size) : KDRT_MALLOC(size, a->user);
}

static void kdrt__free(const kdrt_allocator *a, void *ptr)
{
    if (!ptr) return;
    if (a->free) a->free(a->user, ptr);
    else KDRT_FREE(ptr, a->user);
}

/* *out = a * b, failing instead of wrapping. */
static int kdrt__mul_size(size_t a, size_t b, size_t *out)
{
    if (b != 0 && a > (size_t)-1 / b) return 0;
    *out = a * b;
    return 1;
}

/* ==== input: reading and checking the caller's triangles ==== */

static size_t kdrt__stride(const kdrt_triangles *m)
{
    return m->position_stride ? m->position_stride : 3 * sizeof(float);
}

/* Vertex indices of triangle tri; soups use 3 tri + k (the caller checked it cannot wrap). */
static void kdrt__triangle_indices(const kdrt_triangles *m, uint32_t tri, uint32_t idx[3])
{
    int k;
    for (k = 0; k < 3; ++k)
        idx[k] = m->indices ? m->indices[(size_t)tri * 3 + (size_t)k] : tri * 3u + (uint32_t)k;
}

/* memcpy, because a caller's byte stride may leave the floats unaligned. */
static void kdrt__load_vertex(const kdrt_triangles *m, uint32_t vertex, float out[3])
{
    const unsigned char *base = (const unsigned char *)m->positions;
    memcpy(out, base + (size_t)vertex * m->position_stride, 3 * sizeof(float));
}

static void kdrt__load_mesh_triangle(const kdrt_triangles *m, uint32_t tri, float p[3][3])
{
    uint32_t idx[3];
    kdrt__triangle_indices(m, tri, idx);
    kdrt__load_vertex(m, idx[0], p[0]);
    kdrt__load_vertex(m, idx[1], p[1]);
    kdrt__load_vertex(m, idx[2], p[2]);
}

/* The part holding the tree's triangle number tri: the last one starting at or before it. */
static const kdrt__part *kdrt__part_of(const kdrt__meshes *m, uint32_t tri)
{
    uint32_t lo = 0, hi = m->count - 1u;
    if (m->count == 1) return m->parts; /* every kdrt_tree_build() tree: no search */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo + 1u) / 2u;
        if (m->parts[mid].first <= tri) lo = mid;
        else hi = mid - 1u;
    }
    return &m->parts[lo];
}

/* The corners of the tree's triangle number tri (checked by the build). */
static void kdrt__load_triangle(const kdrt__meshes *m, uint32_t tri, float p[3][3])
{
    const kdrt__part *part = kdrt__part_of(m, tri);
    kdrt__load_mesh_triangle(&part->mesh, tri - part->first, p);
}

/* Checks the view itself; *m gets a resolved copy (stride never 0). */
static kdrt_result kdrt__check_view(const kdrt_triangles *mesh, kdrt_triangles *m)
{
    size_t bytes;
    if (!mesh) return KDRT_ERROR_NULL_ARGUMENT;
    *m = *mesh;
    if (m->position_stride != 0 && m->position_stride < 3 * sizeof(float))
        return KDRT_ERROR_INVALID_STRIDE;
    m->position_stride = kdrt__stride(mesh);
    if (m->triangle_count == 0) return KDRT_SUCCESS;
    if (m->triangle_count > KDRT_MAX_TRIANGLES) return KDRT_ERROR_SIZE_OVERFLOW;
    if (!m->positions) return KDRT_ERROR_NULL_ARGUMENT;
    /* Every vertex byte must be addressable, and so must every index. */
    if (!kdrt__mul_size((size_t)m->vertex_count, m->position_stride, &bytes))
        return KDRT_ERROR_SIZE_OVERFLOW;
    if (!kdrt__mul_size((size_t)m->triangle_count, 3 * sizeof(uint32_t), &bytes))
        return KDRT_ERROR_SIZE_OVERFLOW;
    return KDRT_SUCCESS;
}

/* KDRT_SUCCESS, or why triangle tri cannot be used; its corners go to p when it can. */
static kdrt_result kdrt__check_triangle(const kdrt_triangles *m, uint32_t tri, float p[3][3])
{
    uint32_t idx[3];
    int k, a;
    kdrt__triangle_indices(m, tri, idx);
    if (!m->indices && (uint64_t)tri * 3u + 2u >= m->vertex_count)
        return KDRT_ERROR_INDEX_OUT_OF_RANGE;
    for (k = 0; k < 3; ++k)
        if (idx[k] >= m->vertex_count) return KDRT_ERROR_INDEX_OUT_OF_RANGE;
    for (k = 0; k < 3; ++k) {
        kdrt__load_vertex(m, idx[k], p[k]);
        for (a = 0; a < 3; ++a)
            if (!kdrt__finite(p[k][a])) return KDRT_ERROR_NON_FINITE_VERTEX;
    }
    return KDRT_SUCCESS;
}

/* Coincident or collinear corners. In double the edges and their products lose far less than in
   float, so exact degeneracies (repeated corners, collinear grid points) come out exactly zero. */
static int kdrt__zero_area(float p[3][3])
{
    double e1[3], e2[3], n[3];
    int a;
    for (a = 0; a < 3; ++a) e1[a] = (double)p[1][a] - p[0][a], e2[a] = (double)p[2][a] - p[0][a];
    kdrt__cross(e1, e2, n);
    return n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0;
}

/* ==== version, results and boxes ==== */

KDRT_API const char *kdrt_version(void)
{
    return KDRT_VERSION_STRING;
}

KDRT_API const char *kdrt_result_string(kdrt_result result)
{
    switch (result) {
    case KDRT_SUCCESS: return "success";
    case KDRT_ERROR_NULL_ARGUMENT: return "a required pointer is NULL";
    case KDRT_ERROR_INVALID_STRIDE:
        return "position stride is neither 0 (packed) nor at least 12 bytes";
    case KDRT_ERROR_INVALID_OPTION: return "unknown builder or build flag";
    case KDRT_ERROR_INDEX_OUT_OF_RANGE:
        return "a triangle refers to a vertex at or past vertex_count";
    case KDRT_ERROR_NON_FINITE_VERTEX: return "a triangle has a NaN or infinite coordinate";
    case KDRT_ERROR_SIZE_OVERFLOW: return "a count or byte size is too large to address";
    case KDRT_ERROR_OUT_OF_MEMORY: return "out of memory";
    case KDRT_ERROR_MEDIA_STACK_FULL: return "the medium stack is full (KDRT_MEDIA_STACK_CAPACITY)";
    case KDRT_ERROR_NOT_IN_MEDIUM: return "leaving an object the medium stack does not hold";
    case KDRT_ERROR_INVALID_IOR: return "an index of refraction is NaN, infinite, zero or negative";
    case KDRT_ERROR_INVALID_GEOMETRY_ID:
        return "a scene's geometry ID is used twice, is KDRT_INVALID_ID, or names no instance";
    case KDRT_ERROR_INVALID_TRANSFORM:
        return "an instance transform is singular, has a NaN or infinite entry, or carries its tree beyond float's range";
    case KDRT_ERROR_WRITE_FAILED: return "the write callback failed: the tree is not saved";
    case KDRT_ERROR_NOT_A_SAVED_TREE: return "not a saved kdrt tree (no KDRTTREE magic)";
    case KDRT_ERROR_FILE_VERSION:
        return "a saved tree of another format version than this kdrt reads (save it again)";
    case KDRT_ERROR_FILE_BYTE_ORDER: return "a saved tree whose byte order is not little-endian";
    case KDRT_ERROR_FILE_SIZE:
        return "a saved tree of another size than its header records (truncated, or bytes after its end)";
    case KDRT_ERROR_FILE_CORRUPT:
        return "a saved tree with a field no save writes (damaged or forged)";
    case KDRT_ERROR_MESH_MISMATCH:
        return "the meshes given are not those the tree was saved over (counts or hash differ)";
    case KDRT_ERROR_INVALID_QUERY:
        return "a query's point, box, radius or distance is NaN, infinite or negative where it may not be";
    }
    return "unknown kdrt_result";
}

KDRT_API const char *kdrt_kernel_string(kdrt_kernel kernel)
{
    switch (kernel) {
    case KDRT_KERNEL_SCALAR: return "scalar";
    case KDRT_KERNEL_AVX2: return "avx2";
    case KDRT_KERNEL_AVX512: return "avx512";
    case KDRT_KERNEL_NEON: return "neon";
    case KDRT_KERNEL_SIMD128: return "simd128";
    }
    return "unknown";
}

KDRT_API kdrt_aabb kdrt_aabb_empty(void)
{
    /* min > max on every axis: growing it by any point gives that point's box. */
    kdrt_aabb box;
    int a;
    for (a = 0; a < 3; ++a) {
        box.min[a] = INFINITY;
        box.max[a] = -INFINITY;
    }
    return box;
}

KDRT_API void kdrt_aabb_grow(kdrt_aabb *box, const float point[3])
{
    int a;
    for (a = 0; a < 3; ++a) {
        if (point[a] < box->min[a]) box->min[a] = point[a];
        if (point[a] > box->max[a]) box->max[a] = point[a];
    }
}

KDRT_API kdrt_aabb kdrt_aabb_union(kdrt_aabb a, kdrt_aabb b)
{
    /* Per axis, not by growing a with b's corners: b's corners are infinite when b is empty. */
    int k;
    for (k = 0; k < 3; ++k) {
        if (b.min[k] < a.min[k]) a.min[k] = b.min[k];
        if (b.max[k] > a.max[k]) a.max[k] = b.max[k];
    }
    return a;
}

KDRT_API kdrt_result kdrt_aabb_of_triangles(const kdrt_triangles *mesh, kdrt_aabb *out_box,
                                            kdrt_build_report *report)
{
    kdrt_triangles m;
    kdrt_result r;
    uint32_t tri;
    float p[3][3];
    if (report) {
        memset(report, 0, sizeof *report);
        report->invalid_triangle = report->invalid_geometry = KDRT_INVALID_ID;
    }
    if (!out_box) return KDRT_ERROR_NULL_ARGUMENT;
    *out_box = kdrt_aabb_empty();
    r = kdrt__check_view(mesh, &m);
    if (r != KDRT_SUCCESS) return r;
    for (tri = 0; tri < m.triangle_count; ++tri) {
        r = kdrt__check_triangle(&m, tri, p);
        if (r != KDRT_SUCCESS) {
            if (report) report->invalid_triangle = tri;
            *out_box = kdrt_aabb_empty();
            return r;
        }
        kdrt_aabb_grow(out_box, p[0]);
        kdrt_aabb_grow(out_box, p[1]);
        kdrt_aabb_grow(out_box, p[2]);
    }
    return KDRT_SUCCESS;
}

/* ==== rays: setup and the slab test ==== */

/* pbrt's gamma(3) doubled: (split - o) * (1 / d) is three roundings away from the true distance,
   so the true value lies within t * (1 -+ KDRT__T_SLACK). */
#define KDRT__EPS 5.96046448e-8f /* 2^-24, half an ulp of 1 */
#define KDRT__T_SLACK (2.0f * (3.0f * KDRT__EPS) / (1.0f - 3.0f * KDRT__EPS))

/* kdrt_intersect_k's hits so far, sorted by (t, triangle). */
typedef struct kdrt__hit_list {
    kdrt_hit *hits;
    uint32_t count, capacity;
} kdrt__hit_list;

/* What decides and names a candidate beyond the plain walk: a query's rules, and the tree's
   meshes and instance to name hits by (their geometry ID and own triangle index). */
typedef struct kdrt__rules {
    uint32_t flags;   /* kdrt_query_flags, front and back swapped in a mirroring instance */
    uint32_t mask;    /* the ray's; tested against each part's unless all of those are full */
    int test_mask;
    kdrt_filter_fn filter;
    void *user;
    const kdrt_ray *ray;        /* the caller's (in the world, for an instance), for the filter */
    const kdrt__meshes *meshes; /* the tree's */
    uint32_t instance;          /* the instance being walked, or KDRT_INVALID_ID */
} kdrt__rules;

typedef struct kdrt__ray_setup {
    float org[3], dir[3], inv_dir[3];
    float tmin, tmax;
    kdrt__hit_list *list; /* kdrt_intersect_k's, else NULL: the nearest hit only */
    const kdrt__rules *rules; /* a query's rules or a list, else NULL: every hit counts */
    /* Watertight test: kz is the axis of the largest |dir| component, kx and ky the others
       (swapped when dir[kz] < 0 to keep the winding); the shear maps dir onto +z. */
    int kx, ky, kz;
    float shear_x, shear_y, shear_z;
} kdrt__ray_setup;

/* 0 for rays that can hit nothing: NaN or infinite parts, zero direction, empty range. */
static int kdrt__setup_ray(const kdrt_ray *ray, kdrt__ray_setup *s)
{
    int a, nonzero = 0;
    for (a = 0; a < 3; ++a) {
        if (!kdrt__finite(ray->org[a]) || !kdrt__finite(ray->dir[a])) return 0;
        s->org[a] = ray->org[a];
        s->dir[a] = ray->dir[a];
        s->inv_dir[a] = 1.0f / ray->dir[a]; /* +-0 gives +-infinity, which the slab tests expect */
        nonzero |= ray->dir[a] != 0.0f;
    }
    if (ray->tmin != ray->tmin) return 0; /* NaN */
    s->tmin = ray->tmin > 0.0f ? ray->tmin : 0.0f;
    s->tmax = ray->tmax;
    s->list = NULL, s->rules = NULL;
    if (!nonzero || !(s->tmin <= s->tmax)) return 0; /* also when tmax is NaN */

    s->kz = 0;
    for (a = 1; a < 3; ++a)
        if (kdrt__abs(s->dir[a]) > kdrt__abs(s->dir[s->kz])) s->kz = a;
    s->kx = (s->kz + 1) % 3;
    s->ky = (s->kx + 1) % 3;
    if (s->dir[s->kz] < 0.0f) { int k = s->kx; s->kx = s->ky; s->ky = k; }
    s->shear_x = s->dir[s->kx] / s->dir[s->kz];
    s->shear_y = s->dir[s->ky] / s->dir[s->kz];
    s->shear_z = 1.0f / s->dir[s->kz];
    return 1;
}

/* Slab test. An axis the ray is parallel to (its inverse direction is infinite) is decided by
   the origin alone, which keeps 0 * infinity NaNs out and makes +-0 directions exact. */
static int kdrt__clip_to_box(const kdrt_aabb *box, const kdrt__ray_setup *s, float *t0, float *t1)
{
    float enter = s->tmin, exit = s->tmax;
    int a;
    for (a = 0; a < 3; ++a) {
        float ta, tb, tnear, tfar;
        if (!kdrt__finite(s->inv_dir[a])) {
            if (s->org[a] < box->min[a] || s->org[a] > box->max[a]) return 0;
            continue;
        }
        ta = (box->min[a] - s->org[a]) * s->inv_dir[a];
        tb = (box->max[a] - s->org[a]) * s->inv_dir[a];
        /* Conservative entry and exit (pbrt-v3): a hit on a flat box's triangle may lie a few
           ulps before the rounded entry. */
        tnear = (ta < tb ? ta : tb) * (1.0f - KDRT__T_SLACK);
        tfar = (ta < tb ? tb : ta) * (1.0f + KDRT__T_SLACK);
        if (tnear > enter) enter = tnear;
        if (tfar < exit) exit = tfar;
    }
    *t0 = enter;
    *t1 = exit;
    return enter <= exit;
}

KDRT_API int kdrt_aabb_intersect_ray(const kdrt_aabb *box, const kdrt_ray *ray, float *t_enter,
                                     float *t_exit)
{
    kdrt__ray_setup s;
    float t0, t1;
    int a;
    if (!box || !ray || !kdrt__setup_ray(ray, &s)) return 0;
    for (a = 0; a < 3; ++a)
        if (!(box->min[a] <= box->max[a])) return 0; /* empty or NaN box */
    if (!kdrt__clip_to_box(box, &s, &t0, &t1)) return 0;
    if (t_enter) *t_enter = t0;
    if (t_exit) *t_exit = t1;
    return 1;
}

/* ==== builder state, growing arrays, leaves ==== */

KDRT_API kdrt_build_options kdrt_default_build_options(void)
{
    kdrt_build_options o;
    memset(&o, 0, sizeof o);
    o.builder = KDRT_BUILDER_SAH;
    o.max_leaf_size = KDRT_DEFAULT_MAX_LEAF_SIZE;
    return o;
}

#define KDRT__SIDE_BELOW 1u
#define KDRT__SIDE_ABOVE 2u

typedef struct kdrt__builder {
    const kdrt_allocator *allocator;
    const float *lo, *hi, *centroid; /* per triangle (by caller's index), 3 floats each */
    unsigned char *side;             /* per triangle: KDRT__SIDE_* of the split being made */
    const kdrt__meshes *mesh;        /* the SAH builder clips triangles to node boxes */
    float sah_trav, sah_isect, sah_empty_bonus;
    /* The SAH build's quality: nodes of at most exact_max references sweep every candidate
       (events kept in order); larger ones bin into `bins` bins, and when the bins find no split
       worth making, exact_fallback sweeps every candidate before making a leaf; clip: the
       triangles a plane cuts are clipped to the children (perfect splits), else their boxes. */
    uint32_t exact_max, bins;
    int exact_fallback, clip;
    int sse; /* bins with SSE2 where compiled in; not with KDRT_BUILD_SCALAR_KERNEL */
    int avx2; /* costs bins' planes with AVX2 where compiled in and the CPU has it; not scalar */
    kdrt__node *nodes;
    uint32_t node_count, node_capacity;
    uint32_t *refs;
    uint32_t ref_count, ref_capacity;
    uint32_t max_leaf_size, max_depth;
    uint32_t leaves, depth_reached;
} kdrt__builder;

/* Grows *array (elements of elem_size) to hold at least need; capacity doubles. */
static kdrt_result kdrt__reserve(const kdrt_allocator *a, void **array, uint32_t *capacity,
                                 uint32_t need, size_t elem_size)
{
    uint32_t cap = *capacity;
    size_t bytes;
    void *grown;
    if (need <= cap) return KDRT_SUCCESS;
    cap = cap < 64u ? 64u : cap;
    while (cap < need) cap = cap > 0x7FFFFFFFu ? 0xFFFFFFFFu : cap * 2u;
    if (!kdrt__mul_size(cap, elem_size, &bytes)) return KDRT_ERROR_SIZE_OVERFLOW;
    grown = kdrt__alloc(a, bytes);
    if (!grown) return KDRT_ERROR_OUT_OF_MEMORY;
    if (*array) memcpy(grown, *array, (size_t)*capacity * elem_size);
    kdrt__free(a, *array);
    *array = grown;
    *capacity = cap;
    return KDRT_SUCCESS;
}

/* Trims *array to count elements once the build is done; keeps it as it is if that fails. */
static void kdrt__shrink(const kdrt_allocator *a, void **array, uint32_t *capacity, uint32_t count,
                         size_t elem_size)
{
    void *exact;
    if (count == *capacity || count == 0) return;
    exact = kdrt__alloc(a, (size_t)count * elem_size);
    if (!exact) return;
    memcpy(exact, *array, (size_t)count * elem_size);
    kdrt__free(a, *array);
    *array = exact;
    *capacity = count;
}

static kdrt_result kdrt__emit_leaf(kdrt__builder *b, uint32_t node, const uint32_t *tris,
                                   uint32_t n, uint32_t depth)
{
    kdrt_result r;
    if (n > KDRT_MAX_TRIANGLES || n > 0xFFFFFFFFu - b->ref_count) return KDRT_ERROR_SIZE_OVERFLOW;
    r = kdrt__reserve(b->allocator, (void **)&b->refs, &b->ref_capacity, b->ref_count + n,
                      sizeof(uint32_t));
    if (r != KDRT_SUCCESS) return r;
    if (n) memcpy(b->refs + b->ref_count, tris, (size_t)n * sizeof(uint32_t));
    b->nodes[node] = kdrt__node_leaf(b->ref_count, n);
    b->ref_count += n;
    b->leaves += 1;
    if (depth > b->depth_reached) b->depth_reached = depth;
    return KDRT_SUCCESS;
}

/* ==== median builder ==== */

/* A triangle's centroid on one axis, for the median builder's sort. */
typedef struct kdrt__key {
    float key;
    uint32_t tri;
} kdrt__key;

static int kdrt__key_less(const void *pa, const void *pb)
{
    const kdrt__key *a = (const kdrt__key *)pa, *b = (const kdrt__key *)pb;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->tri < b->tri ? -1 : (a->tri > b->tri); /* a total order: same tree on every libc */
}

/* Marks each triangle's side of the plane; returns the counts below and above. */
static void kdrt__classify(kdrt__builder *b, const uint32_t *tris, uint32_t n, int axis,
                           float split, uint32_t *below, uint32_t *above)
{
    uint32_t i, nb = 0, na = 0;
    for (i = 0; i < n; ++i) {
        uint32_t t = tris[i];
        float lo = b->lo[3 * t + (uint32_t)axis], hi = b->hi[3 * t + (uint32_t)axis];
        unsigned char side = 0;
        if (lo < split || hi <= split) side |= KDRT__SIDE_BELOW; /* planar-in-plane goes below */
        if (hi > split) side |= KDRT__SIDE_ABOVE;
        b->side[t] = side;
        nb += (side & KDRT__SIDE_BELOW) != 0;
        na += (side & KDRT__SIDE_ABOVE) != 0;
    }
    *below = nb;
    *above = na;
}

/* lists holds the node's n triangles three times, sorted by centroid x, y and z. */
static kdrt_result kdrt__build_node(kdrt__builder *b, const uint32_t *lists, uint32_t n,
                                    uint32_t depth)
{
    uint32_t node, nb = 0, na = 0, i, k, attempt, *children;
    int axis = 0;
    float split = 0.0f;
    size_t count;
    kdrt_result r;

    if (b->node_count >= KDRT_MAX_TRIANGLES) return KDRT_ERROR_SIZE_OVERFLOW;
    r = kdrt__reserve(b->allocator, (void **)&b->nodes, &b->node_capacity, b->node_count + 1,
                      sizeof(kdrt__node));
    if (r != KDRT_SUCCESS) return r;
    node = b->node_count++;

    if (n <= b->max_leaf_size || depth >= b->max_depth)
        return kdrt__emit_leaf(b, node, lists, n, depth);

    for (attempt = 0; attempt < 3; ++attempt) {
        axis = (int)((depth + attempt) % 3u);
        split = b->centroid[3 * lists[(size_t)axis * n + n / 2] + (uint32_t)axis];
        kdrt__classify(b, lists + (size_t)axis * n, n, axis, split, &nb, &na);
        if (nb < n && na < n) break;
    }
    if (attempt == 3) return kdrt__emit_leaf(b, node, lists, n, depth); /* separates nothing */

    /* Filtering keeps each axis's order, so the children's lists stay sorted. */
    count = 3u * ((size_t)nb + na);
    children = (uint32_t *)kdrt__alloc(b->allocator, count * sizeof(uint32_t));
    if (!children) return KDRT_ERROR_OUT_OF_MEMORY;
    for (k = 0; k < 3; ++k) {
        uint32_t *below = children + (size_t)k * nb,
                 *above = children + 3u * (size_t)nb + (size_t)k * na;
        const uint32_t *list = lists + (size_t)k * n;
        for (i = 0; i < n; ++i) {
            unsigned char side = b->side[list[i]];
            if (side & KDRT__SIDE_BELOW) *below++ = list[i];
            if (side & KDRT__SIDE_ABOVE) *above++ = list[i];
        }
    }
    r = kdrt__build_node(b, children, nb, depth + 1);
    if (r == KDRT_SUCCESS) {
        /* The below child follows at node + 1; the above child starts here. */
        b->nodes[node] = kdrt__node_inner((uint32_t)axis, split, b->node_count);
        r = kdrt__build_node(b, children + 3u * (size_t)nb, na, depth + 1);
    }
    kdrt__free(b->allocator, children);
    return r;
}

/* ==== SAH builder: perfect splits (clipping a triangle to a node) ==== */

/* A reference: the box of the part of triangle tri that lies inside its node. */
typedef struct kdrt__ref {
    float lo[3], hi[3];
    uint32_t tri;
} kdrt__ref;

/* Box of the polygon pts[0..n), rounded outwards to float and kept within [blo, bhi]; 0 when
   that leaves nothing. */
static int kdrt__polygon_box(double (*pts)[3], int n, const float blo[3], const float bhi[3],
                             float lo[3], float hi[3])
{
    int a, j;
    if (n == 0) return 0;
    for (a = 0; a < 3; ++a) {
        double l = pts[0][a], h = l;
        for (j = 1; j < n; ++j) {
            if (pts[j][a] < l) l = pts[j][a];
            if (pts[j][a] > h) h = pts[j][a];
        }
        lo[a] = kdrt__float_down(l), hi[a] = kdrt__float_up(h); /* round outwards */
        if (lo[a] < blo[a]) lo[a] = blo[a];
        if (hi[a] > bhi[a]) hi[a] = bhi[a];
        if (lo[a] > hi[a]) return 0;
    }
    return 1;
}

/* Perfect split of a triangle the plane cuts: the part of triangle tri inside the node's box
   [child_lo[0], child_hi[1]] (Sutherland-Hodgman in double), cut by the plane into the part in
   each child's box; their boxes go to lo[c], hi[c]. Returns bit c set when child c gets some. */
static unsigned kdrt__clip_split(const kdrt__meshes *m, uint32_t tri, int axis, float pos,
                                 float child_lo[2][3], float child_hi[2][3], float lo[2][3],
                                 float hi[2][3])
{
    double poly[2][9][3], part[2][11][3];
    const float *blo = child_lo[0], *bhi = child_hi[1];
    float p[3][3];
    int n = 3, cur = 0, k, side, i, a, count[2] = {0, 0};
    unsigned result = 0;
    kdrt__load_triangle(m, tri, p);
    for (i = 0; i < 3; ++i)
        for (a = 0; a < 3; ++a) poly[0][i][a] = p[i][a];
    for (k = 0; k < 3 && n > 0; ++k)
        for (side = 0; side < 2 && n > 0; ++side) {
            /* Keep the half space x_k >= blo (side 0) or x_k <= bhi (side 1), boundary included. */
            double plane = side ? bhi[k] : blo[k], sign = side ? -1.0 : 1.0;
            int out = 0;
            /* Most planes cut nothing: skip those with every corner of the triangle inside. */
            if (side ? (p[0][k] <= bhi[k] && p[1][k] <= bhi[k] && p[2][k] <= bhi[k])
                     : (p[0][k] >= blo[k] && p[1][k] >= blo[k] && p[2][k] >= blo[k]))
                continue;
            for (i = 0; i < n; ++i) {
                const double *s = poly[cur][i], *e = poly[cur][(i + 1) % n];
                double ds = sign * (s[k] - plane), de = sign * (e[k] - plane);
                if (ds >= 0.0) memcpy(poly[!cur][out++], s, sizeof poly[0][0]);
                if ((ds < 0.0 && de > 0.0) || (ds > 0.0 && de < 0.0)) {
                    double f = ds / (ds - de);
                    for (a = 0; a < 3; ++a) poly[!cur][out][a] = s[a] + f * (e[a] - s[a]);
                    poly[!cur][out][k] = plane; /* exactly on the plane */
                    ++out;
                }
            }
            n = out;
            cur = !cur;
        }
    /* The cut: corners on the plane go to both parts, as do the points where edges cross it. */
    for (i = 0; i < n; ++i) {
        const double *s = poly[cur][i], *e = poly[cur][(i + 1) % n];
        double ds = s[axis] - (double)pos, de = e[axis] - (double)pos;
        if (ds <= 0.0) memcpy(part[0][count[0]++], s, sizeof part[0][0]);
        if (ds >= 0.0) memcpy(part[1][count[1]++], s, sizeof part[0][0]);
        if ((ds < 0.0 && de > 0.0) || (ds > 0.0 && de < 0.0)) {
            double f = ds / (ds - de);
            for (a = 0; a < 3; ++a) part[0][count[0]][a] = s[a] + f * (e[a] - s[a]);
            part[0][count[0]][axis] = pos;
            memcpy(part[1][count[1]++], part[0][count[0]++], sizeof part[0][0]);
        }
    }
    for (i = 0; i < 2; ++i)
        if (kdrt__polygon_box(part[i], count[i], child_lo[i], child_hi[i], lo[i], hi[i]))
            result |= 1u << i;
    return result;
}

/* ==== arena ==== */

/* Scratch memory given back in stack order, as the depth-first build needs it: a list of chunks
   kept for reuse, so once the path down the tree is warm a node costs no allocation. */
typedef struct kdrt__chunk {
    struct kdrt__chunk *next;
    size_t size, used;
} kdrt__chunk;

typedef struct kdrt__arena {
    const kdrt_allocator *allocator;
    kdrt__chunk *first, *current;
} kdrt__arena;

typedef struct kdrt__mark {
    kdrt__chunk *chunk;
    size_t used;
} kdrt__mark;

#define KDRT__CHUNK_HEADER ((sizeof(kdrt__chunk) + 15u) & ~(size_t)15u)
#define KDRT__FIRST_CHUNK ((size_t)1 << 16)

static void *kdrt__arena_alloc(kdrt__arena *arena, size_t size)
{
    kdrt__chunk *c = arena->current, *next;
    if (size > ((size_t)-1) / 4) return NULL;
    size = (size + 15u) & ~(size_t)15u;
    if (!c || c->size - c->used < size) {
        next = c ? c->next : arena->first;
        if (!next || next->size < size) {
            size_t want = c ? 2 * c->size : KDRT__FIRST_CHUNK;
            if (want < size) want = size;
            next = (kdrt__chunk *)kdrt__alloc(arena->allocator, KDRT__CHUNK_HEADER + want);
            if (!next) return NULL;
            next->size = want;
            next->next = c ? c->next : arena->first; /* a chunk too small stays, further on */
            if (c) c->next = next;
            else arena->first = next;
        }
        next->used = 0;
        arena->current = c = next;
    }
    c->used += size;
    return (char *)c + KDRT__CHUNK_HEADER + (c->used - size);
}

static void kdrt__arena_init(kdrt__arena *arena, const kdrt_allocator *allocator)
{
    arena->allocator = allocator;
    arena->first = arena->current = NULL;
}

static kdrt__mark kdrt__arena_mark(const kdrt__arena *arena)
{
    kdrt__mark m;
    m.chunk = arena->current;
    m.used = m.chunk ? m.chunk->used : 0;
    return m;
}

static void kdrt__arena_release(kdrt__arena *arena, kdrt__mark m)
{
    arena->current = m.chunk;
    if (m.chunk) m.chunk->used = m.used;
}

static void kdrt__arena_free(kdrt__arena *arena)
{
    while (arena->first) {
        kdrt__chunk *next = arena->first->next;
        kdrt__free(arena->allocator, arena->first);
        arena->first = next;
    }
    arena->current = NULL;
}

/* ==== work in chunks on the scheduler ==== */

/* Large arrays of the build (the triangles, a large top node's references, the leaves' blocks)
   are worked on in KDRT__CHUNKS chunks, tasks on options.scheduler; chunks, not threads, so the
   result is the same on any scheduler. */
#define KDRT__CHUNKS 16u
#define KDRT__CHUNK_MIN_REFS 16384u       /* fewer triangles or references: one thread */
#define KDRT__PACK_CHUNK_MIN_BLOCKS 4096u /* fewer blocks are packed on one thread */

static uint32_t kdrt__chunk_start(uint32_t n, uint32_t i)
{
    return (uint32_t)((uint64_t)n * i / KDRT__CHUNKS);
}

/* ==== events ==== */

/* Events of the exact sweep, one uint64_t each: a float's bits turned so that unsigned order is
   numeric order (-0 taken as +0) in the high 32 bits, the event type in bits 30-31 and the index
   of its reference in the node below. At equal positions the sweep takes ends, then planars, then
   starts (Wald & Havran 2006, sec. 4.2). */
#define KDRT__EVENT_END 0u
#define KDRT__EVENT_PLANAR 1u
#define KDRT__EVENT_START 2u
#define KDRT__EVENT_REF_MASK 0x3FFFFFFFu

static uint64_t kdrt__event(float pos, uint32_t type, uint32_t ref)
{
    uint32_t u;
    if (pos == 0.0f) pos = 0.0f;
    memcpy(&u, &pos, sizeof u);
    u = (u & 0x80000000u) ? ~u : u | 0x80000000u;
    return ((uint64_t)u << 32) | ((uint64_t)type << 30) | (ref & KDRT__EVENT_REF_MASK);
}

static float kdrt__event_pos(uint64_t event)
{
    uint32_t u = (uint32_t)(event >> 32);
    float pos;
    u = (u & 0x80000000u) ? u & 0x7FFFFFFFu : ~u;
    memcpy(&pos, &u, sizeof pos);
    return pos;
}

/* Quicksort (median of three, the larger part deferred so the stack stays log2 n deep) with
   insertion sort for short runs, for short arrays: its worst case, quadratic, is then bounded. */
static void kdrt__quicksort_keys(uint64_t *a, size_t n)
{
    size_t stack[2 * 64], sp = 0, lo = 0, hi = n, i, j;
    uint64_t t, pivot;
    for (;;) {
        while (hi - lo > 16) {
            size_t mid = lo + (hi - lo) / 2;
            if (a[mid] < a[lo]) t = a[mid], a[mid] = a[lo], a[lo] = t;
            if (a[hi - 1] < a[lo]) t = a[hi - 1], a[hi - 1] = a[lo], a[lo] = t;
            if (a[hi - 1] < a[mid]) t = a[hi - 1], a[hi - 1] = a[mid], a[mid] = t;
            pivot = a[mid];
            i = lo, j = hi - 1; /* a[lo] <= pivot <= a[hi - 1] bound both scans */
            for (;;) {
                while (a[i] < pivot) ++i;
                while (pivot < a[j]) --j;
                if (i >= j) break;
                t = a[i], a[i] = a[j], a[j] = t;
                ++i, --j;
            }
            /* [lo, j] <= pivot <= [j + 1, hi) */
            if (j + 1 - lo < hi - (j + 1)) stack[sp++] = j + 1, stack[sp++] = hi, hi = j + 1;
            else stack[sp++] = lo, stack[sp++] = j + 1, lo = j + 1;
        }
        for (i = lo + 1; i < hi; ++i) {
            t = a[i];
            for (j = i; j > lo && t < a[j - 1]; --j) a[j] = a[j - 1];
            a[j] = t;
        }
        if (sp == 0) return;
        hi = stack[--sp], lo = stack[--sp];
    }
}

#define KDRT__QUICKSORT_MAX 256u /* longer arrays are radix sorted: linear, whatever the input */

/* Sorts the keys, in O(n) for long arrays (least significant byte first, a pass per byte in
   which the keys differ; scratch from the arena), so that no input can make a build quadratic.
   The keys are totally ordered, so either sort gives the one result. */
static kdrt_result kdrt__sort_keys(kdrt__arena *arena, uint64_t *a, size_t n)
{
    kdrt__mark mark;
    uint64_t *from = a, *to;
    size_t count[256], i, sum;
    unsigned shift;
    if (n <= KDRT__QUICKSORT_MAX) {
        kdrt__quicksort_keys(a, n);
        return KDRT_SUCCESS;
    }
    mark = kdrt__arena_mark(arena);
    to = (uint64_t *)kdrt__arena_alloc(arena, n * sizeof(uint64_t));
    if (!to) return KDRT_ERROR_OUT_OF_MEMORY;
    for (shift = 0; shift < 64; shift += 8) {
        memset(count, 0, sizeof count);
        for (i = 0; i < n; ++i) ++count[(from[i] >> shift) & 255u];
        if (count[(from[0] >> shift) & 255u] == n) continue; /* one byte value: nothing moves */
        for (i = 0, sum = 0; i < 256; ++i) {
            size_t c = count[i];
            count[i] = sum, sum += c;
        }
        for (i = 0; i < n; ++i) to[count[(from[i] >> shift) & 255u]++] = from[i];
        { uint64_t *t = from; from = to, to = t; }
    }
    if (from != a) memcpy(a, from, n * sizeof(uint64_t));
    kdrt__arena_release(arena, mark);
    return KDRT_SUCCESS;
}

/* ==== SAH sweep: costing candidate planes, exact and binned ==== */

typedef struct kdrt__plane {
    int axis; /* -1: no split beats a leaf */
    float pos;
    int planar_below; /* triangles lying in the plane go below (1) or above (0) */
    double cost;
} kdrt__plane;

/* What costing planes on one axis of a node needs, worked out once per axis. Costs are computed
   in double: float areas overflow beyond coordinates of about 1e19 (and lose their low bits to
   subnormals below 1e-19), while double holds every product of two floats, so a mesh scaled by
   a power of two gets the same costs scaled, and the same tree. */
typedef struct kdrt__axis_cost {
    int k;
    float lo, hi;          /* the node's extent on the axis */
    double cap, side;      /* the child boxes' areas are (cap + length * side) / ... */
    double inv_area;       /* ... over the node's half area */
    double trav, isect, isect_empty; /* SAH constants; isect_empty with the empty bonus */
    uint32_t budget;       /* the most references the children may hold together */
} kdrt__axis_cost;

static kdrt__axis_cost kdrt__axis_setup(const kdrt__builder *b, int k, const float lo[3],
                                        const float hi[3], double inv_area, uint32_t budget)
{
    kdrt__axis_cost c;
    int k1 = k == 2 ? 0 : k + 1, k2 = k == 0 ? 2 : k - 1;
    double d1 = (double)hi[k1] - lo[k1], d2 = (double)hi[k2] - lo[k2];
    c.k = k, c.lo = lo[k], c.hi = hi[k], c.cap = d1 * d2, c.side = d1 + d2, c.inv_area = inv_area;
    c.trav = b->sah_trav, c.isect = b->sah_isect,
    c.isect_empty = b->sah_isect * (1.0 - (double)b->sah_empty_bonus);
    c.budget = budget;
    return c;
}

/* What a leaf of n triangles costs to test, in block tests: its blocks of 8 (kdrt__pack_blocks). */
static double kdrt__leaf_blocks(uint64_t n) { return (double)((n + KDRT__LANES - 1u) / KDRT__LANES); }

/* Costs the plane pos with below, planars and above triangles on its sides, planars going
   either way, and keeps it in best if cheaper. Triangles the plane cuts are counted on both
   sides, so below + planars + above is what the children would hold: over the budget, the plane
   is not a candidate. */
static void kdrt__consider(const kdrt__axis_cost *c, kdrt__plane *best, float pos, uint32_t below,
                           uint32_t planars, uint32_t above)
{
    double p_below, p_above, scale, cost;
    if (!(pos > c->lo && pos < c->hi)) return; /* a plane on the box's face separates nothing */
    if ((uint64_t)below + planars + above > c->budget) return;
    p_below = (c->cap + ((double)pos - c->lo) * c->side) * c->inv_area;
    p_above = (c->cap + ((double)c->hi - pos) * c->side) * c->inv_area;
    scale = (below + planars == 0 || above == 0) ? c->isect_empty : c->isect;
    cost = c->trav + scale * (p_below * kdrt__leaf_blocks((uint64_t)below + planars) +
                              p_above * kdrt__leaf_blocks(above));
    if (cost < best->cost)
        best->axis = c->k, best->pos = pos, best->planar_below = 1, best->cost = cost;
    if (planars == 0) return; /* the same plane again: no better */
    scale = (below == 0 || above + planars == 0) ? c->isect_empty : c->isect;
    cost = c->trav + scale * (p_below * kdrt__leaf_blocks(below) +
                              p_above * kdrt__leaf_blocks((uint64_t)above + planars));
    if (cost < best->cost)
        best->axis = c->k, best->pos = pos, best->planar_below = 0, best->cost = cost;
}

/* A reference's events on axis k (one for a box flat on the axis, else two); returns how many. */
static uint32_t kdrt__push_events(const kdrt__ref *ref, uint32_t index, int k, uint64_t *out)
{
    float l = ref->lo[k], h = ref->hi[k];
    if (l == h) {
        out[0] = kdrt__event(l, KDRT__EVENT_PLANAR, index);
        return 1;
    }
    out[0] = kdrt__event(l, KDRT__EVENT_START, index);
    out[1] = kdrt__event(h, KDRT__EVENT_END, index);
    return 2;
}

/* The sweep over one axis's sorted events of a node of n references: every distinct position is
   a candidate plane, costed with the counts on its sides. */
static void kdrt__sweep(const kdrt__axis_cost *cost, const uint64_t *events, size_t count,
                        uint32_t n, kdrt__plane *best)
{
    size_t i = 0;
    uint32_t below = 0, above = n;
    while (i < count) {
        uint32_t at = (uint32_t)(events[i] >> 32), ends = 0, planars = 0, starts = 0;
        float pos = kdrt__event_pos(events[i]);
        for (; i < count && (uint32_t)(events[i] >> 32) == at; ++i) {
            uint32_t type = (uint32_t)(events[i] >> 30) & 3u;
            ends += type == KDRT__EVENT_END;
            planars += type == KDRT__EVENT_PLANAR;
            starts += type == KDRT__EVENT_START;
        }
        above -= planars + ends;
        kdrt__consider(cost, best, pos, below, planars, above);
        below += starts + planars;
    }
}

/* At most KDRT_SAH_EXACT_MAX references, every candidate plane is tried, from each axis's events
   kept in order (Wald & Havran 2006): sorted once where a subtree comes down to that size, then
   split in order at every node, so that a node costs O(n) and only the events of the references
   its plane cuts are made and sorted again. */
typedef struct kdrt__events {
    uint64_t *axis[3];
    size_t count[3];
} kdrt__events;

/* Each axis's events of refs[0..n), sorted, in arrays from the arena (room for 2n + 1 each: the
   spare slot is kdrt__child_events'). */
static kdrt_result kdrt__sorted_events(kdrt__arena *arena, const kdrt__ref *refs, uint32_t n,
                                       kdrt__events *out)
{
    uint32_t r;
    int k;
    for (k = 0; k < 3; ++k) {
        out->axis[k] = (uint64_t *)kdrt__arena_alloc(arena, (2 * (size_t)n + 1) * sizeof(uint64_t));
        if (!out->axis[k]) return KDRT_ERROR_OUT_OF_MEMORY;
        out->count[k] = 0;
        for (r = 0; r < n; ++r)
            out->count[k] += kdrt__push_events(&refs[r], r, k, out->axis[k] + out->count[k]);
        if (kdrt__sort_keys(arena, out->axis[k], out->count[k]) != KDRT_SUCCESS)
            return KDRT_ERROR_OUT_OF_MEMORY;
    }
    return KDRT_SUCCESS;
}

/* Each axis's events of refs[0..n), sorted, in arrays from the allocator (owned by the caller,
   who frees them with kdrt__free_events, whatever the result): for HIGH's top, whose events go
   from node to node until the tasks. With a scheduler each axis is a task, sorting in an arena
   of its own. */
typedef struct kdrt__axis_sort {
    const kdrt_allocator *allocator;
    const kdrt__ref *refs;
    uint32_t n;
    kdrt__events *out;
    kdrt_result result[3];
} kdrt__axis_sort;

static void kdrt__sort_axis(void *data, uint32_t k)
{
    kdrt__axis_sort *job = (kdrt__axis_sort *)data;
    uint64_t *events =
        (uint64_t *)kdrt__alloc(job->allocator, (2 * (size_t)job->n + 1) * sizeof(uint64_t));
    size_t count = 0;
    uint32_t r;
    kdrt__arena scratch;
    job->out->axis[k] = events, job->out->count[k] = 0;
    job->result[k] = KDRT_ERROR_OUT_OF_MEMORY;
    if (!events) return;
    for (r = 0; r < job->n; ++r) count += kdrt__push_events(&job->refs[r], r, (int)k, events + count);
    job->out->count[k] = count;
    kdrt__arena_init(&scratch, job->allocator);
    job->result[k] = kdrt__sort_keys(&scratch, events, count);
    kdrt__arena_free(&scratch);
}

static void kdrt__free_events(const kdrt_allocator *a, kdrt__events *e)
{
    int k;
    for (k = 0; k < 3; ++k) kdrt__free(a, e->axis[k]), e->axis[k] = NULL;
}

static kdrt_result kdrt__sorted_events_owned(const kdrt_allocator *a,
                                             const kdrt_scheduler *scheduler,
                                             const kdrt__ref *refs, uint32_t n, kdrt__events *out)
{
    kdrt__axis_sort job;
    uint32_t k;
    job.allocator = a, job.refs = refs, job.n = n, job.out = out;
    if (scheduler && scheduler->run && n >= KDRT__CHUNK_MIN_REFS)
        scheduler->run(scheduler->user, kdrt__sort_axis, &job, 3);
    else
        for (k = 0; k < 3; ++k) kdrt__sort_axis(&job, k);
    return job.result[0] != KDRT_SUCCESS ? job.result[0]
           : job.result[1] != KDRT_SUCCESS ? job.result[1] : job.result[2];
}

/* Binned sweep for large nodes: each axis cut into b->bins equal bins (KDRT_SAH_BINS, or FAST's
   32), a reference counted in the bins of its two faces, and the planes between bins costed from
   those counts. O(n). */

/* A reference's bin from its position f in bins (0 to top = bins - 1 inside the node): clamped as
   a float, so the conversion never sees a value out of range, and NaN goes to bin 0. */
static uint32_t kdrt__bin(float f, float top)
{
    f = f > 0.0f ? f : 0.0f;
    f = f < top ? f : top;
    return (uint32_t)f;
}

/* A node's bins: per axis, how many references' boxes start and end in each bin. */
typedef struct kdrt__bins {
    uint32_t count; /* bins per axis: b->bins */
    int sse;        /* binned and costed with SSE2 (kdrt__bin_refs, kdrt__bins_plane) */
    int avx2;       /* costed with AVX2 */
    float top;      /* count - 1, the last bin */
    float lo[4], scale[4]; /* the node's box: bin of x = (x - lo) * scale, clamped; [3] unused */
    uint32_t starts[3][KDRT_SAH_BINS], ends[3][KDRT_SAH_BINS];
} kdrt__bins;

static void kdrt__bins_init(const kdrt__builder *b, const float lo[3], const float hi[3],
                            kdrt__bins *bins)
{
    int k;
    bins->count = b->bins; /* at most KDRT_SAH_BINS */
    bins->sse = b->sse, bins->avx2 = b->avx2, bins->top = (float)(b->bins - 1u);
    bins->lo[3] = bins->scale[3] = 0.0f;
    for (k = 0; k < 3; ++k) {
        bins->lo[k] = lo[k];
        bins->scale[k] = hi[k] > lo[k] ? (float)bins->count / (hi[k] - lo[k]) : 0.0f;
        memset(bins->starts[k], 0, bins->count * sizeof(uint32_t));
        memset(bins->ends[k], 0, bins->count * sizeof(uint32_t));
    }
}

/* The bin of position x on axis k. */
static uint32_t kdrt__bin_at(const kdrt__bins *bins, int k, float x)
{
    return kdrt__bin((x - bins->lo[k]) * bins->scale[k], bins->top);
}

/* Counts refs[0..n) into bins. SSE2 bins a reference's three axes at once, each lane rounding
   and clamping as kdrt__bin does (max returns its second operand for NaN, which kdrt__bin sends
   to 0 too), so the bins and the tree are the same either way. */
static void kdrt__bin_refs(const kdrt__ref *refs, uint32_t n, kdrt__bins *bins)
{
    uint32_t r;
    int k;
#if KDRT__SSE2
    if (bins->sse) {
        /* The reference's six floats as two overlapping loads, lo[0..2] hi[0] and lo[2] hi[0..2]
           (never its triangle number, whose bits would be a subnormal float), each lane with
           its axis's offset and scale. */
        const __m128 lo_a = _mm_setr_ps(bins->lo[0], bins->lo[1], bins->lo[2], bins->lo[0]);
        const __m128 lo_b = _mm_setr_ps(bins->lo[2], bins->lo[0], bins->lo[1], bins->lo[2]);
        const __m128 scale_a =
            _mm_setr_ps(bins->scale[0], bins->scale[1], bins->scale[2], bins->scale[0]);
        const __m128 scale_b =
            _mm_setr_ps(bins->scale[2], bins->scale[0], bins->scale[1], bins->scale[2]);
        const __m128 zero = _mm_setzero_ps(), top = _mm_set1_ps(bins->top);
        for (r = 0; r < n; ++r) {
            uint32_t at[8]; /* starts x, y, z, end x; then start z, ends x, y, z */
            __m128 f = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(refs[r].lo), lo_a), scale_a);
            __m128 g = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(refs[r].lo + 2), lo_b), scale_b);
            f = _mm_min_ps(_mm_max_ps(f, zero), top), g = _mm_min_ps(_mm_max_ps(g, zero), top);
            _mm_storeu_si128((__m128i *)(void *)at, _mm_cvttps_epi32(f));
            _mm_storeu_si128((__m128i *)(void *)(at + 4), _mm_cvttps_epi32(g));
            bins->starts[0][at[0]] += 1, bins->starts[1][at[1]] += 1, bins->starts[2][at[2]] += 1;
            bins->ends[0][at[3]] += 1, bins->ends[1][at[6]] += 1, bins->ends[2][at[7]] += 1;
        }
        return;
    }
#endif
    for (r = 0; r < n; ++r)
        for (k = 0; k < 3; ++k) {
            bins->starts[k][kdrt__bin_at(bins, k, refs[r].lo[k])] += 1;
            bins->ends[k][kdrt__bin_at(bins, k, refs[r].hi[k])] += 1;
        }
}

/* Bounds on what each child of plane will hold, from the bins of a node of n references: the
   references are then split in one pass, without counting them first. A position's bin never
   falls as the position grows (a subtraction and a product by a scale >= 0, each rounded, then
   clamped and truncated), so a reference that reaches below the plane starts in the plane's bin
   or before, and one that reaches above it ends in the plane's bin or after. A bin of slack
   each side keeps the bound safe (the split writes up to it) should a position ever be binned
   a bin off, by a compiler's rounding, here and in kdrt__bin_refs. */
static void kdrt__bins_room(const kdrt__bins *bins, uint32_t n, const kdrt__plane *plane,
                            uint32_t room[2])
{
    const int k = plane->axis;
    const uint32_t at = kdrt__bin_at(bins, k, plane->pos);
    uint32_t i, below = 0, ended = 0;
    for (i = 0; i <= at + 1u && i < bins->count; ++i) below += bins->starts[k][i];
    for (i = 0; i + 2u <= at; ++i) ended += bins->ends[k][i];
    room[0] = below, room[1] = n - ended;
}

#if KDRT__SSE2
/* Blocks of 8 (kdrt__leaf_blocks) of 4 counts: n / 8, plus one for a remainder, no overflow. */
static __m128i kdrt__blocks_sse2(__m128i n)
{
    const __m128i seven = _mm_set1_epi32(7);
    return _mm_add_epi32(_mm_srli_epi32(n, 3),
                         _mm_srli_epi32(_mm_add_epi32(_mm_and_si128(n, seven), seven), 3));
}

/* The planes between the bins of one axis of a node of n references, from 1 to planes: how
   many references each has below and above, and whether those fit the budget (all ones or 0),
   padded with zeros to a multiple of 8. */
static void kdrt__bins_counts(const kdrt__axis_cost *c, const kdrt__bins *bins, uint32_t n,
                              uint32_t *below, uint32_t *above, uint32_t *fits)
{
    uint32_t i, sum = 0, ended = 0;
    const uint32_t planes = bins->count - 1u;
    /* Children hold at most 2n: within a budget of that, every plane fits (the usual case). */
    const int all_fit = 2 * (uint64_t)n <= c->budget;
    for (i = 0; i < planes; ++i) {
        sum += bins->starts[c->k][i], ended += bins->ends[c->k][i];
        below[i] = sum, above[i] = n - ended;
        fits[i] = all_fit || (uint64_t)sum + (n - ended) <= c->budget ? 0xFFFFFFFFu : 0u;
    }
    for (; i % 8u; ++i) below[i] = above[i] = fits[i] = 0;
}

/* Planes pos[0..lanes) of axis k, costing cost[]: the cheapest kept where it beats best, in
   order, the first of equal costs kept, as in the scalar loop. */
static void kdrt__keep_cheapest(int k, const float *pos, const double *cost, uint32_t lanes,
                                kdrt__plane *best)
{
    uint32_t j;
    for (j = 0; j < lanes; ++j)
        if (cost[j] < best->cost)
            best->axis = k, best->pos = pos[j], best->planar_below = 1, best->cost = cost[j];
}

/* Costs the planes between the bins on one axis of a node of n references 4 at a time, by the
   operations of kdrt__consider (no planars) in the same order, each rounding as there
   (contraction is off): the costs, and so the plane kept, are the scalar loop's bit for bit. */
static void kdrt__bins_costs_sse2(const kdrt__axis_cost *c, const kdrt__bins *bins, uint32_t n,
                                  kdrt__plane *best)
{
    uint32_t below[KDRT_SAH_BINS + 7], above[KDRT_SAH_BINS + 7], fits[KDRT_SAH_BINS + 7];
    uint32_t i;
    const uint32_t planes = bins->count - 1u;
    const __m128 lo = _mm_set1_ps(c->lo), hi = _mm_set1_ps(c->hi);
    const __m128 length = _mm_set1_ps(c->hi - c->lo), count = _mm_set1_ps((float)bins->count);
    const __m128d lo_d = _mm_set1_pd((double)c->lo), hi_d = _mm_set1_pd((double)c->hi);
    const __m128d cap = _mm_set1_pd(c->cap), side = _mm_set1_pd(c->side);
    const __m128d inv_area = _mm_set1_pd(c->inv_area), trav = _mm_set1_pd(c->trav);
    const __m128d isect = _mm_set1_pd(c->isect), isect_empty = _mm_set1_pd(c->isect_empty);
    const __m128d inf = _mm_set1_pd(INFINITY);
    const __m128i zero = _mm_setzero_si128();
    kdrt__bins_counts(c, bins, n, below, above, fits);
    for (i = 0; i < planes; i += 4) {
        const __m128i nb = _mm_loadu_si128((const __m128i *)(const void *)(below + i));
        const __m128i na = _mm_loadu_si128((const __m128i *)(const void *)(above + i));
        const __m128i bb = kdrt__blocks_sse2(nb), ba = kdrt__blocks_sse2(na);
        const __m128 at =
            _mm_cvtepi32_ps(_mm_setr_epi32((int)i + 1, (int)i + 2, (int)i + 3, (int)i + 4));
        const __m128 pos = _mm_add_ps(lo, _mm_mul_ps(length, _mm_div_ps(at, count)));
        /* Inside the box (not on a face, not NaN) and within the budget. */
        const __m128 inside = _mm_and_ps(_mm_cmpgt_ps(pos, lo), _mm_cmplt_ps(pos, hi));
        const __m128i ok = _mm_and_si128(
            _mm_loadu_si128((const __m128i *)(const void *)(fits + i)), _mm_castps_si128(inside));
        const __m128i empty = _mm_or_si128(_mm_cmpeq_epi32(nb, zero), _mm_cmpeq_epi32(na, zero));
        const __m128d least = _mm_set1_pd(best->cost);
        float at_pos[4];
        double cost[4];
        int h, cheaper = 0;
        for (h = 0; h < 2; ++h) { /* lanes 2h and 2h + 1, in double */
            const __m128d p = _mm_cvtps_pd(h ? _mm_movehl_ps(pos, pos) : pos);
            const __m128d e = _mm_castsi128_pd(h ? _mm_unpackhi_epi32(empty, empty)
                                                 : _mm_unpacklo_epi32(empty, empty));
            const __m128d valid =
                _mm_castsi128_pd(h ? _mm_unpackhi_epi32(ok, ok) : _mm_unpacklo_epi32(ok, ok));
            const __m128d blocks_below = _mm_cvtepi32_pd(h ? _mm_srli_si128(bb, 8) : bb);
            const __m128d blocks_above = _mm_cvtepi32_pd(h ? _mm_srli_si128(ba, 8) : ba);
            const __m128d p_below =
                _mm_mul_pd(_mm_add_pd(cap, _mm_mul_pd(_mm_sub_pd(p, lo_d), side)), inv_area);
            const __m128d p_above =
                _mm_mul_pd(_mm_add_pd(cap, _mm_mul_pd(_mm_sub_pd(hi_d, p), side)), inv_area);
            const __m128d scale =
                _mm_or_pd(_mm_and_pd(e, isect_empty), _mm_andnot_pd(e, isect));
            const __m128d sah = _mm_add_pd(
                trav, _mm_mul_pd(scale, _mm_add_pd(_mm_mul_pd(p_below, blocks_below),
                                                   _mm_mul_pd(p_above, blocks_above))));
            const __m128d kept = _mm_or_pd(_mm_and_pd(valid, sah), _mm_andnot_pd(valid, inf));
            cheaper |= _mm_movemask_pd(_mm_cmplt_pd(kept, least));
            _mm_storeu_pd(cost + 2 * h, kept);
        }
        if (!cheaper) continue; /* the usual case: none beats the best so far */
        _mm_storeu_ps(at_pos, pos);
        kdrt__keep_cheapest(c->k, at_pos, cost, 4, best);
    }
}
#endif

#if defined(KDRT__AVX2)
/* kdrt__bins_costs_sse2 8 planes at a time, the doubles 4 at a time: the same operations in the
   same order (the target has no FMA to fuse them), so the same costs bit for bit. */
KDRT__TARGET_AVX2 static void kdrt__bins_costs_avx2(const kdrt__axis_cost *c,
                                                    const kdrt__bins *bins, uint32_t n,
                                                    kdrt__plane *best)
{
    uint32_t below[KDRT_SAH_BINS + 7], above[KDRT_SAH_BINS + 7], fits[KDRT_SAH_BINS + 7];
    uint32_t i;
    const uint32_t planes = bins->count - 1u;
    const __m256 lo = _mm256_set1_ps(c->lo), hi = _mm256_set1_ps(c->hi);
    const __m256 length = _mm256_set1_ps(c->hi - c->lo);
    const __m256 count = _mm256_set1_ps((float)bins->count);
    const __m256 first = _mm256_setr_ps(1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f, 8.0f);
    const __m256d lo_d = _mm256_set1_pd((double)c->lo), hi_d = _mm256_set1_pd((double)c->hi);
    const __m256d cap = _mm256_set1_pd(c->cap), side = _mm256_set1_pd(c->side);
    const __m256d inv_area = _mm256_set1_pd(c->inv_area), trav = _mm256_set1_pd(c->trav);
    const __m256d isect = _mm256_set1_pd(c->isect), isect_empty = _mm256_set1_pd(c->isect_empty);
    const __m256d inf = _mm256_set1_pd(INFINITY);
    const __m256i zero = _mm256_setzero_si256(), seven = _mm256_set1_epi32(7);
    kdrt__bins_counts(c, bins, n, below, above, fits);
    for (i = 0; i < planes; i += 8) {
        const __m256i nb = _mm256_loadu_si256((const __m256i *)(const void *)(below + i));
        const __m256i na = _mm256_loadu_si256((const __m256i *)(const void *)(above + i));
        /* blocks of 8, as kdrt__blocks_sse2 */
        const __m256i bb = _mm256_add_epi32(
            _mm256_srli_epi32(nb, 3),
            _mm256_srli_epi32(_mm256_add_epi32(_mm256_and_si256(nb, seven), seven), 3));
        const __m256i ba = _mm256_add_epi32(
            _mm256_srli_epi32(na, 3),
            _mm256_srli_epi32(_mm256_add_epi32(_mm256_and_si256(na, seven), seven), 3));
        /* i + 1 to i + 8 exactly: i is below 2^24 */
        const __m256 at = _mm256_add_ps(_mm256_set1_ps((float)i), first);
        const __m256 pos = _mm256_add_ps(lo, _mm256_mul_ps(length, _mm256_div_ps(at, count)));
        const __m256 inside = _mm256_and_ps(_mm256_cmp_ps(pos, lo, _CMP_GT_OQ),
                                            _mm256_cmp_ps(pos, hi, _CMP_LT_OQ));
        const __m256i ok = _mm256_and_si256(
            _mm256_loadu_si256((const __m256i *)(const void *)(fits + i)),
            _mm256_castps_si256(inside));
        const __m256i empty =
            _mm256_or_si256(_mm256_cmpeq_epi32(nb, zero), _mm256_cmpeq_epi32(na, zero));
        const __m256d least = _mm256_set1_pd(best->cost);
        float at_pos[8];
        double cost[8];
        int h, cheaper = 0;
        for (h = 0; h < 2; ++h) { /* lanes 4h to 4h + 3, in double */
            const __m256d p = _mm256_cvtps_pd(h ? _mm256_extractf128_ps(pos, 1)
                                                : _mm256_castps256_ps128(pos));
            /* each 32-bit mask widened to 64 bits by sign extension */
            const __m256d e = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(
                h ? _mm256_extracti128_si256(empty, 1) : _mm256_castsi256_si128(empty)));
            const __m256d valid = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(
                h ? _mm256_extracti128_si256(ok, 1) : _mm256_castsi256_si128(ok)));
            const __m256d blocks_below = _mm256_cvtepi32_pd(
                h ? _mm256_extracti128_si256(bb, 1) : _mm256_castsi256_si128(bb));
            const __m256d blocks_above = _mm256_cvtepi32_pd(
                h ? _mm256_extracti128_si256(ba, 1) : _mm256_castsi256_si128(ba));
            const __m256d p_below = _mm256_mul_pd(
                _mm256_add_pd(cap, _mm256_mul_pd(_mm256_sub_pd(p, lo_d), side)), inv_area);
            const __m256d p_above = _mm256_mul_pd(
                _mm256_add_pd(cap, _mm256_mul_pd(_mm256_sub_pd(hi_d, p), side)), inv_area);
            const __m256d scale = _mm256_blendv_pd(isect, isect_empty, e);
            const __m256d sah = _mm256_add_pd(
                trav, _mm256_mul_pd(scale, _mm256_add_pd(_mm256_mul_pd(p_below, blocks_below),
                                                         _mm256_mul_pd(p_above, blocks_above))));
            const __m256d kept = _mm256_blendv_pd(inf, sah, valid);
            cheaper |= _mm256_movemask_pd(_mm256_cmp_pd(kept, least, _CMP_LT_OQ));
            _mm256_storeu_pd(cost + 4 * h, kept);
        }
        if (!cheaper) continue; /* the usual case: none beats the best so far */
        _mm256_storeu_ps(at_pos, pos);
        kdrt__keep_cheapest(c->k, at_pos, cost, 8, best);
    }
}
#endif

/* The planes between bins of a node of n references, costed from the bins' counts. */
static void kdrt__bins_plane(const kdrt__builder *b, const kdrt__bins *bins, uint32_t n,
                             const float lo[3], const float hi[3], double inv_area,
                             uint32_t budget, kdrt__plane *best)
{
    uint32_t i;
    int k;
    for (k = 0; k < 3; ++k) {
        uint32_t below = 0, ended = 0;
        kdrt__axis_cost cost;
        if (bins->scale[k] == 0.0f) continue;
        cost = kdrt__axis_setup(b, k, lo, hi, inv_area, budget);
#if defined(KDRT__AVX2)
        if (bins->avx2) {
            kdrt__bins_costs_avx2(&cost, bins, n, best);
            continue;
        }
#endif
#if KDRT__SSE2
        if (bins->sse) {
            kdrt__bins_costs_sse2(&cost, bins, n, best);
            continue;
        }
#endif
        for (i = 1; i < bins->count; ++i) {
            below += bins->starts[k][i - 1], ended += bins->ends[k][i - 1];
            kdrt__consider(&cost, best, lo[k] + (hi[k] - lo[k]) * ((float)i / (float)bins->count),
                           below, 0, n - ended);
        }
    }
}

/* ==== SAH node: choosing the plane, splitting references and events ==== */

static double kdrt__half_area(const float lo[3], const float hi[3])
{
    double dx = (double)hi[0] - lo[0], dy = (double)hi[1] - lo[1], dz = (double)hi[2] - lo[2];
    return dx * dy + dy * dz + dz * dx;
}

/* Which side of the plane a reference lies on: KDRT__SIDE_BELOW, _ABOVE, or both when the plane
   cuts its box. */
static unsigned kdrt__ref_side(const kdrt__ref *r, int axis, float pos, unsigned planar_side)
{
    /* Without branches: which side is all but random from one reference to the next. A box
       (lo <= hi) on neither side lies in the plane, and goes to planar_side. */
    const float l = r->lo[axis], h = r->hi[axis];
    const unsigned side =
        (unsigned)(l < pos) * KDRT__SIDE_BELOW | (unsigned)(h > pos) * KDRT__SIDE_ABOVE;
    return side | (unsigned)(side == 0) * planar_side;
}

/* The children's references, in arrays from the arena (or, with no arena, at the top of a
   parallel build, from the allocator): a reference on one side is copied, one the plane cuts is
   split by kdrt__clip_split (perfect splits) and goes only where some of the triangle lies, or
   (FAST, no clipping) has its box cut at the plane. bound[c] is at least what child c gets
   (kdrt__bins_room), or KDRT_INVALID_ID: then the sides are counted first. When sides is not
   NULL it gets each reference's side, and index[c] where it went in child c (or
   KDRT_INVALID_ID). */
static kdrt_result kdrt__split_refs(const kdrt__builder *b, kdrt__arena *arena,
                                    const kdrt__ref *refs, uint32_t n, const kdrt__plane *plane,
                                    const uint32_t bound[2], float child_lo[2][3],
                                    float child_hi[2][3], kdrt__ref *child[2], uint32_t count[2],
                                    unsigned char *sides, uint32_t *index[2])
{
    /* The plane in locals: the compiler cannot tell the children's writes from it. */
    const int axis = plane->axis;
    const float pos = plane->pos;
    const unsigned planar_side = plane->planar_below ? KDRT__SIDE_BELOW : KDRT__SIDE_ABOVE;
    uint32_t room[2] = {0, 0}, kept[2] = {0, 0}, r, c;
    kdrt__ref *below, *above;
    if (bound[0] != KDRT_INVALID_ID && bound[1] != KDRT_INVALID_ID) {
        room[0] = bound[0], room[1] = bound[1];
    } else {
        for (r = 0; r < n; ++r) {
            unsigned side = kdrt__ref_side(&refs[r], axis, pos, planar_side);
            room[0] += side & KDRT__SIDE_BELOW, room[1] += side >> 1;
        }
    }
    for (c = 0; c < 2; ++c) {
        /* One to spare: a reference is written to both sides and kept on its own. */
        size_t bytes = ((size_t)room[c] + 1) * sizeof(kdrt__ref);
        child[c] = (kdrt__ref *)(arena ? kdrt__arena_alloc(arena, bytes)
                                       : kdrt__alloc(b->allocator, bytes));
        if (!child[c]) return KDRT_ERROR_OUT_OF_MEMORY;
        count[c] = 0;
    }
    /* In locals, as the plane is: written through, they would be read again every time. */
    below = child[0], above = child[1];
    for (r = 0; r < n; ++r) {
        const kdrt__ref *ref = &refs[r];
        unsigned side = kdrt__ref_side(ref, axis, pos, planar_side), into = side;
        float lo[2][3], hi[2][3];
        if (sides) sides[r] = (unsigned char)side;
        if (side != (KDRT__SIDE_BELOW | KDRT__SIDE_ABOVE)) {
            /* Most references: copied to both, kept where they lie, without a branch (the spare
               slot takes the write past the last kept one). */
            const uint32_t keep_below = side & KDRT__SIDE_BELOW, keep_above = side >> 1;
            below[kept[0]] = *ref, above[kept[1]] = *ref;
            if (sides) {
                index[0][r] = keep_below ? kept[0] : KDRT_INVALID_ID;
                index[1][r] = keep_above ? kept[1] : KDRT_INVALID_ID;
            }
            kept[0] += keep_below, kept[1] += keep_above;
            continue;
        }
        if (b->clip) {
            into = kdrt__clip_split(b->mesh, ref->tri, axis, pos, child_lo, child_hi, lo, hi);
        } else {
            /* The box split at the plane, each part kept by the side it lies on. */
            memcpy(lo[0], ref->lo, sizeof lo[0]), memcpy(hi[0], ref->hi, sizeof hi[0]);
            memcpy(lo[1], ref->lo, sizeof lo[1]), memcpy(hi[1], ref->hi, sizeof hi[1]);
            hi[0][axis] = lo[1][axis] = pos;
        }
        for (c = 0; c < 2; ++c) {
            kdrt__ref *out = &child[c][kept[c]];
            if (sides) index[c][r] = (into >> c) & 1u ? kept[c] : KDRT_INVALID_ID;
            if (!((into >> c) & 1u)) continue;
            memcpy(out->lo, lo[c], sizeof out->lo), memcpy(out->hi, hi[c], sizeof out->hi);
            out->tri = ref->tri;
            ++kept[c];
        }
    }
    count[0] = kept[0], count[1] = kept[1];
    KDRT_ASSERT(count[0] <= room[0] && count[1] <= room[1]);
    return KDRT_SUCCESS;
}

/* The reference budget: a node's subtree may hold at most `budget` references at any depth (the
   root's is KDRT_SAH_REFERENCE_BUDGET per triangle). A split is made only when its children hold
   at most that many together; they then share it in proportion to what each holds, so each
   child's budget covers its own references and the two add up to no more than their parent's.
   Every level of the tree, the leaves included, holds at most the root's budget. */
static int kdrt__share_budget(uint32_t budget, const uint32_t count[2], uint32_t out[2])
{
    uint64_t total = (uint64_t)count[0] + count[1];
    int c;
    if (total > budget) return 0;
    for (c = 0; c < 2; ++c) out[c] = total ? (uint32_t)((uint64_t)budget * count[c] / total) : 0;
    return 1;
}

static void kdrt__child_boxes(const float lo[3], const float hi[3], const kdrt__plane *plane,
                              float child_lo[2][3], float child_hi[2][3])
{
    int c;
    for (c = 0; c < 2; ++c)
        memcpy(child_lo[c], lo, 3 * sizeof(float)), memcpy(child_hi[c], hi, 3 * sizeof(float));
    child_hi[0][plane->axis] = plane->pos, child_lo[1][plane->axis] = plane->pos;
}

/* Every candidate on the three axes, from a node's sorted events. */
static void kdrt__sweep_axes(const kdrt__builder *b, const kdrt__events *events, uint32_t n,
                             const float lo[3], const float hi[3], double inv_area,
                             uint32_t budget, kdrt__plane *best)
{
    int k;
    for (k = 0; k < 3; ++k) {
        kdrt__axis_cost cost = kdrt__axis_setup(b, k, lo, hi, inv_area, budget);
        kdrt__sweep(&cost, events->axis[k], events->count[k], n, best);
    }
}

/* A large node at the top of a parallel build is binned in KDRT__CHUNKS chunks of its references,
   tasks on the scheduler: the chunks' counts add up to the same bins on any scheduler, or none.
   (Splitting the references in chunks too was slower on 2 cores: bench/README.md.) */

typedef struct kdrt__chunked {
    const kdrt__ref *refs;
    uint32_t n;
    kdrt__bins *bins; /* KDRT__CHUNKS of them */
} kdrt__chunked;

static void kdrt__bin_chunk(void *data, uint32_t i)
{
    kdrt__chunked *c = (kdrt__chunked *)data;
    uint32_t begin = kdrt__chunk_start(c->n, i), end = kdrt__chunk_start(c->n, i + 1u);
    kdrt__bin_refs(c->refs + begin, end - begin, &c->bins[i]);
}

/* refs[0..n) binned in chunks on the scheduler, their counts summed into *out (initialised for
   the node's box [lo, hi]). */
static kdrt_result kdrt__bin_refs_chunked(const kdrt__builder *b, const kdrt_scheduler *scheduler,
                                          const kdrt__ref *refs, uint32_t n, const float lo[3],
                                          const float hi[3], kdrt__bins *out)
{
    kdrt__chunked c;
    uint32_t i, j;
    int k;
    c.refs = refs, c.n = n;
    c.bins = (kdrt__bins *)kdrt__alloc(b->allocator, KDRT__CHUNKS * sizeof(kdrt__bins));
    if (!c.bins) return KDRT_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < KDRT__CHUNKS; ++i) kdrt__bins_init(b, lo, hi, &c.bins[i]);
    scheduler->run(scheduler->user, kdrt__bin_chunk, &c, KDRT__CHUNKS);
    for (i = 0; i < KDRT__CHUNKS; ++i)
        for (k = 0; k < 3; ++k)
            for (j = 0; j < out->count; ++j)
                out->starts[k][j] += c.bins[i].starts[k][j], out->ends[k][j] += c.bins[i].ends[k][j];
    kdrt__free(b->allocator, c.bins);
    return KDRT_SUCCESS;
}

/* The node's split, or axis -1 for a leaf: at most max_leaf_size triangles, at max_depth, or no
   plane within the budget cheaper than testing all n (cost-based termination). With events (the
   exact region) every candidate is tried; without, the bins choose, and where they find nothing
   worth a split every candidate is tried before the node is made a leaf. room gets bounds on
   the children's sizes where the node was binned (kdrt__bins_room), else KDRT_INVALID_ID. */
static kdrt_result kdrt__choose_plane(const kdrt__builder *b, kdrt__arena *arena,
                                      const kdrt_scheduler *scheduler, const kdrt__ref *refs,
                                      uint32_t n, const kdrt__events *events, const float lo[3],
                                      const float hi[3], uint32_t depth, uint32_t budget,
                                      kdrt__plane *best, uint32_t room[2])
{
    kdrt__bins bins;
    double area = kdrt__half_area(lo, hi), leaf_cost = (double)b->sah_isect * kdrt__leaf_blocks(n);
    int binned = 0;
    best->axis = -1, best->pos = 0.0f, best->planar_below = 1, best->cost = INFINITY;
    room[0] = room[1] = KDRT_INVALID_ID;
    if (n <= b->max_leaf_size || depth >= b->max_depth || !(area > 0.0)) return KDRT_SUCCESS;
    if (events) {
        kdrt__sweep_axes(b, events, n, lo, hi, 1.0 / area, budget, best);
    } else {
        if (b->exact_max < n || n > KDRT__EVENT_REF_MASK) {
            binned = 1;
            kdrt__bins_init(b, lo, hi, &bins);
            if (scheduler && scheduler->run && n >= KDRT__CHUNK_MIN_REFS) {
                if (kdrt__bin_refs_chunked(b, scheduler, refs, n, lo, hi, &bins) != KDRT_SUCCESS)
                    return KDRT_ERROR_OUT_OF_MEMORY;
            } else {
                kdrt__bin_refs(refs, n, &bins);
            }
            kdrt__bins_plane(b, &bins, n, lo, hi, 1.0 / area, budget, best);
        }
        if (!(best->cost < leaf_cost) && b->exact_fallback && n <= KDRT__EVENT_REF_MASK) {
            kdrt__mark mark = kdrt__arena_mark(arena);
            kdrt__events all;
            if (kdrt__sorted_events(arena, refs, n, &all) != KDRT_SUCCESS)
                return KDRT_ERROR_OUT_OF_MEMORY;
            kdrt__sweep_axes(b, &all, n, lo, hi, 1.0 / area, budget, best);
            kdrt__arena_release(arena, mark);
        }
    }
    if (!(best->cost < leaf_cost)) best->axis = -1;
    else if (binned) kdrt__bins_room(&bins, n, best, room);
    return KDRT_SUCCESS;
}

/* The children's events, still in order: the node's events of the references wholly on one
   side, renumbered as index says (which keeps their order), merged with fresh, sorted events of
   the references the plane cut, made from their clipped boxes. */
static kdrt_result kdrt__child_events(kdrt__arena *arena, const kdrt_allocator *owner,
                                      const kdrt__events *events, uint32_t n,
                                      const unsigned char *sides, uint32_t *const index[2],
                                      kdrt__ref *const child[2], const uint32_t count[2],
                                      kdrt__events out[2])
{
    const unsigned cut = KDRT__SIDE_BELOW | KDRT__SIDE_ABOVE;
    uint64_t *fresh = (uint64_t *)kdrt__arena_alloc(arena, (2 * (size_t)n + 1) * sizeof(uint64_t));
    uint32_t *cut_refs[2], cuts[2] = {0, 0}, r, c;
    int k;
    cut_refs[0] = (uint32_t *)kdrt__arena_alloc(arena, (2 * (size_t)n + 1) * sizeof(uint32_t));
    if (!fresh || !cut_refs[0]) return KDRT_ERROR_OUT_OF_MEMORY;
    /* Each child's index of every reference the plane cut that went to it, gathered once
       rather than per axis. */
    cut_refs[1] = cut_refs[0] + n;
    for (r = 0; r < n; ++r)
        for (c = 0; c < 2; ++c)
            if (sides[r] == cut && index[c][r] != KDRT_INVALID_ID)
                cut_refs[c][cuts[c]++] = index[c][r];
    for (k = 0; k < 3; ++k) {
        size_t i, kept[2] = {0, 0};
        for (c = 0; c < 2; ++c) {
            const size_t bytes = (2 * (size_t)count[c] + 1) * sizeof(uint64_t);
            out[c].axis[k] = (uint64_t *)(owner ? kdrt__alloc(owner, bytes)
                                                : kdrt__arena_alloc(arena, bytes));
            if (!out[c].axis[k]) return KDRT_ERROR_OUT_OF_MEMORY;
        }
        /* Written on both sides and kept on one: no branch to mispredict (each array has a slot
           to spare for the write past its last kept event). A reference missing from a side
           has index KDRT_INVALID_ID there, masked to a harmless number. */
        for (i = 0; i < events->count[k]; ++i) {
            uint64_t e = events->axis[k][i], at = e & ~(uint64_t)KDRT__EVENT_REF_MASK;
            uint32_t ref = (uint32_t)e & KDRT__EVENT_REF_MASK;
            out[0].axis[k][kept[0]] = at | (index[0][ref] & KDRT__EVENT_REF_MASK);
            out[1].axis[k][kept[1]] = at | (index[1][ref] & KDRT__EVENT_REF_MASK);
            kept[0] += sides[ref] == KDRT__SIDE_BELOW;
            kept[1] += sides[ref] == KDRT__SIDE_ABOVE;
        }
        for (c = 0; c < 2; ++c) {
            uint64_t *o = out[c].axis[k];
            size_t made = 0, w;
            for (r = 0; r < cuts[c]; ++r)
                made +=
                    kdrt__push_events(&child[c][cut_refs[c][r]], cut_refs[c][r], k, fresh + made);
            if (kdrt__sort_keys(arena, fresh, made) != KDRT_SUCCESS)
                return KDRT_ERROR_OUT_OF_MEMORY;
            out[c].count[k] = kept[c] + made;
            for (i = kept[c], w = kept[c] + made; made > 0;) /* merge from the back, in place */
                o[--w] = (i > 0 && o[i - 1] > fresh[made - 1]) ? o[--i] : fresh[--made];
        }
    }
    return KDRT_SUCCESS;
}

/* Builds the subtree of a node with box [lo, hi] and n <= budget references into b, depth first
   (the below child right after its parent); events are the node's sorted events in the exact
   region, NULL above it. Scratch memory comes from the arena and is back there on return.
   Above the exact region the references are arrays from the allocator, each owned by its node
   (owned: this call frees refs, as soon as the children have theirs): the arrays alive at any
   moment then belong to nodes none of which lies above another, which share the budget, so the
   build's scratch stays within the budget however deep the tree. */
static kdrt_result kdrt__sah_node(kdrt__builder *b, kdrt__arena *arena, kdrt__ref *refs,
                                  uint32_t n, int owned, const kdrt__events *events,
                                  const float lo[3], const float hi[3], uint32_t depth,
                                  uint32_t budget)
{
    kdrt__mark mark = kdrt__arena_mark(arena);
    kdrt__ref *child[2] = {NULL, NULL};
    kdrt__events entry, child_events[2];
    unsigned char *sides = NULL;
    uint32_t node = 0, count[2] = {0, 0}, child_budget[2] = {0, 0}, *index[2] = {NULL, NULL}, i;
    uint32_t room[2] = {KDRT_INVALID_ID, KDRT_INVALID_ID};
    float child_lo[2][3], child_hi[2][3];
    kdrt__plane plane;
    kdrt_result r = KDRT_SUCCESS;
    int binned;

    plane.axis = -1;
    if (!events && n <= b->exact_max && n <= KDRT__EVENT_REF_MASK) {
        /* Down to the exact region: each axis's events sorted, once for the whole subtree. */
        r = kdrt__sorted_events(arena, refs, n, &entry);
        events = &entry;
    }
    binned = !events; /* the children's arrays come from the allocator, owned by them */
    if (r == KDRT_SUCCESS && b->node_count >= KDRT_MAX_TRIANGLES) r = KDRT_ERROR_SIZE_OVERFLOW;
    if (r == KDRT_SUCCESS)
        r = kdrt__reserve(b->allocator, (void **)&b->nodes, &b->node_capacity,
                          b->node_count + 1, sizeof(kdrt__node));
    if (r == KDRT_SUCCESS) {
        node = b->node_count++;
        r = kdrt__choose_plane(b, arena, NULL, refs, n, events, lo, hi, depth, budget, &plane,
                               room);
    }
    if (r == KDRT_SUCCESS && plane.axis >= 0) {
        kdrt__child_boxes(lo, hi, &plane, child_lo, child_hi);
        if (events) {
            sides = (unsigned char *)kdrt__arena_alloc(arena, (size_t)n + 1);
            index[0] = (uint32_t *)kdrt__arena_alloc(arena, ((size_t)n + 1) * sizeof(uint32_t));
            index[1] = (uint32_t *)kdrt__arena_alloc(arena, ((size_t)n + 1) * sizeof(uint32_t));
            if (!sides || !index[0] || !index[1]) r = KDRT_ERROR_OUT_OF_MEMORY;
        }
        if (r == KDRT_SUCCESS)
            r = kdrt__split_refs(b, binned ? NULL : arena, refs, n, &plane, room, child_lo,
                                 child_hi, child, count, sides, index);
        /* The bins' counts can be off by a reference or two: the real ones decide. */
        if (r == KDRT_SUCCESS && !kdrt__share_budget(budget, count, child_budget)) plane.axis = -1;
    }
    if (r == KDRT_SUCCESS && plane.axis < 0) {
        uint32_t *tris = (uint32_t *)kdrt__arena_alloc(arena, ((size_t)n + 1) * sizeof(uint32_t));
        if (!tris) r = KDRT_ERROR_OUT_OF_MEMORY;
        for (i = 0; tris && i < n; ++i) tris[i] = refs[i].tri;
        if (tris) r = kdrt__emit_leaf(b, node, tris, n, depth);
    }
    if (owned) kdrt__free(b->allocator, refs); /* the children have their own */
    if (r == KDRT_SUCCESS && plane.axis >= 0) {
        if (events)
            r = kdrt__child_events(arena, NULL, events, n, sides, index, child, count, child_events);
        if (r == KDRT_SUCCESS)
            r = kdrt__sah_node(b, arena, child[0], count[0], binned,
                               events ? &child_events[0] : NULL, child_lo[0], child_hi[0],
                               depth + 1, child_budget[0]);
        child[0] = NULL; /* freed by its node */
        if (r == KDRT_SUCCESS) {
            b->nodes[node] = kdrt__node_inner((uint32_t)plane.axis, plane.pos, b->node_count);
            r = kdrt__sah_node(b, arena, child[1], count[1], binned,
                               events ? &child_events[1] : NULL, child_lo[1], child_hi[1],
                               depth + 1, child_budget[1]);
            child[1] = NULL;
        }
    }
    if (binned) kdrt__free(b->allocator, child[0]), kdrt__free(b->allocator, child[1]);
    kdrt__arena_release(arena, mark);
    return r;
}

/* ==== parallel top and join ==== */

/* A parallel build cuts the top of the tree, serially, into subtrees built as independent tasks
   and then joined in depth-first order. Where it cuts depends only on the input, never on the
   threads, so every scheduler (or none) gives the same tree. */
#define KDRT__TASK_DEPTH 6        /* at most 2^6 tasks */
#define KDRT__TASK_MIN_REFS 4096u /* smaller nodes are not worth a task of their own */
#define KDRT__TOP_NODES ((1u << (KDRT__TASK_DEPTH + 1)) - 1u)

typedef struct kdrt__task {
    kdrt__builder out; /* the subtree, its nodes and refs numbered from 0 */
    kdrt__ref *refs;   /* its references, owned until the task has run */
    kdrt__events events; /* HIGH: their sorted events, owned likewise; else all NULL */
    uint32_t n, depth, budget;
    float lo[3], hi[3];
    kdrt_result result;
} kdrt__task;

typedef struct kdrt__top {
    kdrt__node nodes[KDRT__TOP_NODES]; /* the cut's inner nodes; a leaf here is task u.first */
    uint32_t node_count;
    kdrt__task tasks[1u << KDRT__TASK_DEPTH];
    uint32_t task_count;
    uint32_t largest_first[1u << KDRT__TASK_DEPTH]; /* the order tasks are handed out in */
} kdrt__top;

static void kdrt__run_task(void *data, uint32_t index)
{
    kdrt__top *top = (kdrt__top *)data;
    kdrt__task *t = &top->tasks[top->largest_first[index]];
    kdrt__arena arena;
    kdrt__arena_init(&arena, t->out.allocator);
    t->result = kdrt__sah_node(&t->out, &arena, t->refs, t->n, 1,
                               t->events.axis[0] ? &t->events : NULL, t->lo, t->hi, t->depth,
                               t->budget);
    t->refs = NULL; /* the subtree's root freed them */
    kdrt__free_events(t->out.allocator, &t->events);
    kdrt__arena_free(&arena);
}

/* The top of the tree: splits large nodes and hands the rest to tasks. Takes ownership of refs
   and of events' arrays (HIGH: the node's sorted events, handed on to the children in order, as
   the exact region does, so that no node of the top sorts again; else NULL). */
static kdrt_result kdrt__sah_top(const kdrt__builder *b, const kdrt_scheduler *scheduler,
                                 kdrt__top *top, kdrt__ref *refs, kdrt__events *events, uint32_t n,
                                 const float lo[3], const float hi[3], uint32_t depth,
                                 uint32_t budget)
{
    kdrt__ref *child[2] = {NULL, NULL};
    kdrt__events child_events[2];
    uint32_t node = top->node_count++, count[2] = {0, 0}, child_budget[2] = {0, 0};
    uint32_t room[2] = {KDRT_INVALID_ID, KDRT_INVALID_ID};
    uint32_t *index[2] = {NULL, NULL};
    unsigned char *sides = NULL;
    float child_lo[2][3], child_hi[2][3];
    kdrt__plane plane;
    kdrt_result r = KDRT_SUCCESS;
    kdrt__arena arena;
    int c;

    memset(child_events, 0, sizeof child_events);
    plane.axis = -1;
    kdrt__arena_init(&arena, b->allocator);
    if (n > KDRT__TASK_MIN_REFS && depth < KDRT__TASK_DEPTH)
        r = kdrt__choose_plane(b, &arena, scheduler, refs, n, events, lo, hi, depth, budget,
                               &plane, room);
    if (r == KDRT_SUCCESS && plane.axis >= 0) {
        kdrt__child_boxes(lo, hi, &plane, child_lo, child_hi);
        if (events) {
            sides = (unsigned char *)kdrt__arena_alloc(&arena, (size_t)n + 1);
            index[0] = (uint32_t *)kdrt__arena_alloc(&arena, ((size_t)n + 1) * sizeof(uint32_t));
            index[1] = (uint32_t *)kdrt__arena_alloc(&arena, ((size_t)n + 1) * sizeof(uint32_t));
            if (!sides || !index[0] || !index[1]) r = KDRT_ERROR_OUT_OF_MEMORY;
        }
        if (r == KDRT_SUCCESS)
            r = kdrt__split_refs(b, NULL, refs, n, &plane, room, child_lo, child_hi, child, count,
                                 sides, index);
        if (r == KDRT_SUCCESS && !kdrt__share_budget(budget, count, child_budget)) {
            kdrt__free(b->allocator, child[0]), kdrt__free(b->allocator, child[1]);
            child[0] = child[1] = NULL;
            plane.axis = -1; /* over the budget after all: the node goes to a task */
        }
        if (r == KDRT_SUCCESS && plane.axis >= 0 && events)
            r = kdrt__child_events(&arena, b->allocator, events, n, sides, index, child, count,
                                   child_events);
    }
    kdrt__arena_free(&arena);
    if (r != KDRT_SUCCESS) {
        kdrt__free(b->allocator, refs);
        if (events) kdrt__free_events(b->allocator, events);
        for (c = 0; c < 2; ++c)
            kdrt__free(b->allocator, child[c]), kdrt__free_events(b->allocator, &child_events[c]);
        return r;
    }
    if (plane.axis < 0) {
        kdrt__task *t = &top->tasks[top->task_count];
        t->out = *b;
        t->out.nodes = NULL, t->out.node_count = t->out.node_capacity = 0;
        t->out.refs = NULL, t->out.ref_count = t->out.ref_capacity = 0;
        t->out.leaves = t->out.depth_reached = 0;
        t->refs = refs, t->n = n, t->depth = depth, t->budget = budget, t->result = KDRT_SUCCESS;
        if (events) t->events = *events;
        else memset(&t->events, 0, sizeof t->events);
        memcpy(t->lo, lo, sizeof t->lo), memcpy(t->hi, hi, sizeof t->hi);
        top->nodes[node] = kdrt__node_leaf(top->task_count++, 0); /* u.first: the task */
        return KDRT_SUCCESS;
    }
    kdrt__free(b->allocator, refs); /* the children have theirs */
    if (events) kdrt__free_events(b->allocator, events);
    r = kdrt__sah_top(b, scheduler, top, child[0], events ? &child_events[0] : NULL, count[0],
                      child_lo[0], child_hi[0], depth + 1, child_budget[0]);
    top->nodes[node] = kdrt__node_inner((uint32_t)plane.axis, plane.pos, top->node_count);
    if (r == KDRT_SUCCESS)
        return kdrt__sah_top(b, scheduler, top, child[1], events ? &child_events[1] : NULL,
                             count[1], child_lo[1], child_hi[1], depth + 1, child_budget[1]);
    kdrt__free(b->allocator, child[1]);
    kdrt__free_events(b->allocator, &child_events[1]);
    return r;
}

/* Appends top node i's subtree to b, taking each task's nodes and refs renumbered. b's arrays
   have room for all. */
static void kdrt__join(kdrt__builder *b, const kdrt__top *top, uint32_t i)
{
    const kdrt__node *n = &top->nodes[i];
    uint32_t node = b->node_count, k;
    if (kdrt__node_is_leaf(n)) {
        const kdrt__builder *t = &top->tasks[n->u.first].out;
        for (k = 0; k < t->node_count; ++k) {
            const kdrt__node *c = &t->nodes[k];
            b->nodes[node + k] =
                kdrt__node_is_leaf(c)
                    ? kdrt__node_leaf(c->u.first + b->ref_count, kdrt__node_count(c))
                    : kdrt__node_inner(kdrt__node_axis(c), c->u.split, kdrt__node_above(c) + node);
        }
        if (t->ref_count)
            memcpy(b->refs + b->ref_count, t->refs, (size_t)t->ref_count * sizeof(uint32_t));
        b->node_count += t->node_count, b->ref_count += t->ref_count;
        b->leaves += t->leaves;
        if (t->depth_reached > b->depth_reached) b->depth_reached = t->depth_reached;
        return;
    }
    b->node_count += 1;
    kdrt__join(b, top, i + 1);
    b->nodes[node] = kdrt__node_inner(kdrt__node_axis(n), n->u.split, b->node_count);
    kdrt__join(b, top, kdrt__node_above(n));
}

/* The SAH build: the top, the tasks (on the caller's scheduler, or one after the other), then
   the join. Takes ownership of refs. */
static kdrt_result kdrt__sah_build(kdrt__builder *b, const kdrt_scheduler *scheduler,
                                   kdrt__ref *refs, uint32_t n, const float lo[3],
                                   const float hi[3])
{
    kdrt__top *top = (kdrt__top *)kdrt__alloc(b->allocator, sizeof *top);
    kdrt__events root_events, *events = NULL;
    uint64_t nodes = 0, total_refs = 0, budget = (uint64_t)KDRT_SAH_REFERENCE_BUDGET * n;
    uint32_t i;
    kdrt_result r;
    if (!top) { kdrt__free(b->allocator, refs); return KDRT_ERROR_OUT_OF_MEMORY; }
    if (budget > 0xFFFFFFFFu) budget = 0xFFFFFFFFu; /* the most references a tree can address */
    top->node_count = top->task_count = 0;
    memset(&root_events, 0, sizeof root_events);
    if (b->exact_max >= n && n <= KDRT__EVENT_REF_MASK && n > KDRT__TASK_MIN_REFS) {
        /* HIGH, with a top to split: the events sorted once, at the root. */
        r = kdrt__sorted_events_owned(b->allocator, scheduler, refs, n, &root_events);
        if (r != KDRT_SUCCESS) {
            kdrt__free_events(b->allocator, &root_events);
            kdrt__free(b->allocator, refs), kdrt__free(b->allocator, top);
            return r;
        }
        events = &root_events;
    }
    r = kdrt__sah_top(b, scheduler, top, refs, events, n, lo, hi, 0, (uint32_t)budget);
    if (r == KDRT_SUCCESS) {
        /* Largest first, so that no thread is left with a big task at the end (the order
           changes only the timing: each task's subtree goes where its index says). */
        for (i = 0; i < top->task_count; ++i) {
            uint32_t j = i;
            for (; j > 0 && top->tasks[top->largest_first[j - 1]].n < top->tasks[i].n; --j)
                top->largest_first[j] = top->largest_first[j - 1];
            top->largest_first[j] = i;
        }
        if (scheduler && scheduler->run)
            scheduler->run(scheduler->user, kdrt__run_task, top, top->task_count);
        else for (i = 0; i < top->task_count; ++i) kdrt__run_task(top, i);
        for (i = 0; i < top->task_count && r == KDRT_SUCCESS; ++i) r = top->tasks[i].result;
    }
    if (r == KDRT_SUCCESS) {
        nodes = top->node_count - top->task_count;
        for (i = 0; i < top->task_count; ++i)
            nodes += top->tasks[i].out.node_count, total_refs += top->tasks[i].out.ref_count;
        if (nodes > KDRT_MAX_TRIANGLES || total_refs > 0xFFFFFFFFu) r = KDRT_ERROR_SIZE_OVERFLOW;
    }
    if (r == KDRT_SUCCESS)
        r = kdrt__reserve(b->allocator, (void **)&b->nodes, &b->node_capacity, (uint32_t)nodes,
                          sizeof(kdrt__node));
    if (r == KDRT_SUCCESS)
        r = kdrt__reserve(b->allocator, (void **)&b->refs, &b->ref_capacity,
                          (uint32_t)total_refs + 1, sizeof(uint32_t));
    if (r == KDRT_SUCCESS) kdrt__join(b, top, 0);
    for (i = 0; i < top->task_count; ++i) {
        kdrt__free(b->allocator, top->tasks[i].refs); /* set only if the task never ran */
        kdrt__free_events(b->allocator, &top->tasks[i].events);
        kdrt__free(b->allocator, top->tasks[i].out.nodes);
        kdrt__free(b->allocator, top->tasks[i].out.refs);
    }
    kdrt__free(b->allocator, top);
    return r;
}

/* ==== packing: the leaves' triangles in blocks ==== */

/* Lays the leaves' triangles out in blocks once a builder has made the nodes and refs: each leaf,
   in node order (depth first), gets ceil(count / 8) consecutive blocks of its triangles' corners,
   and its node's u.first becomes its first block. block_refs numbers the references the same
   way, leaf by leaf, for the inspection API. The floats are the caller's, so no answer changes.
   With a scheduler, the nodes are packed in KDRT__CHUNKS ranges as tasks, each range's first
   block and reference counted beforehand: the same blocks either way. */
typedef struct kdrt__packing {
    const kdrt__meshes *mesh;
    kdrt__node *nodes;
    const uint32_t *refs;
    kdrt_tree *tree;
    uint32_t node_start[KDRT__CHUNKS + 1], block_start[KDRT__CHUNKS], ref_start[KDRT__CHUNKS];
} kdrt__packing;

static void kdrt__pack_range(void *data, uint32_t chunk)
{
    kdrt__packing *p = (kdrt__packing *)data;
    kdrt_tree *tree = p->tree;
    uint32_t i, b = p->block_start[chunk], ref = p->ref_start[chunk];
    for (i = p->node_start[chunk]; i < p->node_start[chunk + 1]; ++i) {
        kdrt__node *n = &p->nodes[i];
        uint32_t first, total, k, lane;
        if (!kdrt__node_is_leaf(n)) continue;
        first = n->u.first, total = kdrt__node_count(n);
        n->u.first = b;
        for (k = 0; k < total; k += KDRT__LANES, ++b) {
            kdrt__block *block = &tree->blocks[b];
            tree->block_refs[b] = ref + k;
            for (lane = 0; lane < KDRT__LANES; ++lane) {
                const uint32_t tri = p->refs[first + (k + lane < total ? k + lane : total - 1u)];
                float c[3][3];
                int corner, axis;
                kdrt__load_triangle(p->mesh, tri, c);
                for (corner = 0; corner < 3; ++corner)
                    for (axis = 0; axis < 3; ++axis)
                        block->corner[3 * corner + axis][lane] = c[corner][axis];
                block->id[lane] = tri;
            }
        }
        ref += total;
    }
}

static kdrt_result kdrt__pack_blocks(const kdrt_allocator *a, const kdrt_scheduler *scheduler,
                                     const kdrt__meshes *m, kdrt__node *nodes,
                                     uint32_t node_count, const uint32_t *refs, kdrt_tree *tree)
{
    kdrt__packing p;
    uint32_t i, chunk = 0, count = 0, ref = 0;
    size_t bytes;
    p.mesh = m, p.nodes = nodes, p.refs = refs, p.tree = tree;
    for (i = 0; i <= KDRT__CHUNKS; ++i) p.node_start[i] = kdrt__chunk_start(node_count, i);
    for (i = 0; i < node_count; ++i) {
        /* Where each range starts: the blocks and references of the leaves before it. */
        for (; chunk < KDRT__CHUNKS && p.node_start[chunk] == i; ++chunk)
            p.block_start[chunk] = count, p.ref_start[chunk] = ref;
        if (kdrt__node_is_leaf(&nodes[i])) {
            count += (kdrt__node_count(&nodes[i]) + KDRT__LANES - 1u) / KDRT__LANES;
            ref += kdrt__node_count(&nodes[i]);
        }
    }
    for (; chunk < KDRT__CHUNKS; ++chunk) p.block_start[chunk] = count, p.ref_start[chunk] = ref;
    tree->stats.blocks = count; /* at most the references, so no overflow */
    if (count == 0) {
        for (i = 0; i < node_count; ++i)
            if (kdrt__node_is_leaf(&nodes[i])) nodes[i].u.first = 0;
        return KDRT_SUCCESS;
    }
    if (!kdrt__mul_size(count, sizeof(kdrt__block), &bytes) || bytes > (size_t)-1 - 63u)
        return KDRT_ERROR_SIZE_OVERFLOW;
    tree->block_memory = kdrt__alloc(a, bytes + 63u);
    tree->block_refs = (uint32_t *)kdrt__alloc(a, (size_t)count * sizeof(uint32_t));
    if (!tree->block_memory || !tree->block_refs) return KDRT_ERROR_OUT_OF_MEMORY;
    /* 64-byte aligned: a block is five whole cache lines. */
    tree->blocks = (kdrt__block *)((char *)tree->block_memory +
                                   ((64u - (uintptr_t)tree->block_memory % 64u) % 64u));
    if (scheduler && scheduler->run && count >= KDRT__PACK_CHUNK_MIN_BLOCKS)
        scheduler->run(scheduler->user, kdrt__pack_range, &p, KDRT__CHUNKS);
    else
        for (i = 0; i < KDRT__CHUNKS; ++i) kdrt__pack_range(&p, i);
    return KDRT_SUCCESS;
}

/* ==== depth limit and SAH cost ==== */

static uint32_t kdrt__default_depth(uint32_t n)
{
    uint32_t log2n = 0, depth;
    while ((n >> log2n) > 1u) ++log2n;
    depth = 8u + (13u * log2n + 5u) / 10u; /* 8 + 1.3 log2 n, pbrt-v3 */
    return depth < KDRT_MAX_DEPTH ? depth : KDRT_MAX_DEPTH;
}

/* kdrt_tree_stats.sah_cost of a finished tree: a walk with an explicit stack, each node's box cut
   from its parent's at the split. Both builders split inside the node's box: a plane beyond it
   would leave one child as large as the node, which neither accepts. */
static double kdrt__sah_cost(const kdrt_tree *tree, double traversal_cost, double intersection_cost)
{
    struct { uint32_t node; float lo[3], hi[3]; } stack[KDRT_MAX_DEPTH], at;
    double root_area = kdrt__half_area(tree->bounds.min, tree->bounds.max), cost = 0.0;
    unsigned sp = 0;
    if (tree->stats.triangles == 0 || !(root_area > 0.0))
        return intersection_cost * kdrt__leaf_blocks(tree->stats.triangle_refs); /* empty: 0 */
    at.node = 0;
    memcpy(at.lo, tree->bounds.min, sizeof at.lo);
    memcpy(at.hi, tree->bounds.max, sizeof at.hi);
    for (;;) {
        const kdrt__node *node = &tree->nodes[at.node];
        double share = kdrt__half_area(at.lo, at.hi) / root_area;
        int axis = (int)kdrt__node_axis(node);
        if (kdrt__node_is_leaf(node)) {
            cost += share * intersection_cost * kdrt__leaf_blocks(kdrt__node_count(node));
            if (sp == 0) return cost;
            at = stack[--sp];
            continue;
        }
        cost += share * traversal_cost;
        KDRT_ASSERT(sp < KDRT_MAX_DEPTH && at.lo[axis] <= node->u.split &&
                    node->u.split <= at.hi[axis]);
        stack[sp] = at; /* the above child, for later */
        stack[sp].node = kdrt__node_above(node);
        stack[sp++].lo[axis] = node->u.split;
        at.node += 1; /* the below child follows its parent */
        at.hi[axis] = node->u.split;
    }
}

/* ==== kdrt_tree_build and its steps ==== */

/* Options: KDRT_ERROR_INVALID_OPTION for an unknown builder, intersector or flag (a load's
   KDRT_LOAD_IN_PLACE too: the loads take it off first) or a cost out of range,
   KDRT_ERROR_NULL_ARGUMENT for an allocator with one hook of the two. */
static kdrt_result kdrt__check_options(const kdrt_build_options *opt)
{
    if (opt->builder != KDRT_BUILDER_DEFAULT && opt->builder != KDRT_BUILDER_MEDIAN &&
        opt->builder != KDRT_BUILDER_SAH)
        return KDRT_ERROR_INVALID_OPTION;
    if (opt->quality != KDRT_BUILD_QUALITY_DEFAULT && opt->quality != KDRT_BUILD_QUALITY_FAST &&
        opt->quality != KDRT_BUILD_QUALITY_MEDIUM && opt->quality != KDRT_BUILD_QUALITY_HIGH)
        return KDRT_ERROR_INVALID_OPTION;
    /* Negated comparisons also turn NaN away. */
    if (!(opt->sah_traversal_cost >= 0.0f) || !(opt->sah_intersection_cost >= 0.0f) ||
        !(opt->sah_empty_bonus >= 0.0f && opt->sah_empty_bonus < 1.0f) ||
        !kdrt__finite(opt->sah_traversal_cost) || !kdrt__finite(opt->sah_intersection_cost))
        return KDRT_ERROR_INVALID_OPTION;
    if (opt->intersector != KDRT_INTERSECTOR_DEFAULT &&
        opt->intersector != KDRT_INTERSECTOR_WATERTIGHT &&
        opt->intersector != KDRT_INTERSECTOR_FAST)
        return KDRT_ERROR_INVALID_OPTION;
    if (opt->flags & ~(uint32_t)(KDRT_BUILD_SKIP_INVALID_TRIANGLES | KDRT_BUILD_SCALAR_KERNEL |
                                 KDRT_BUILD_AVX2_KERNEL))
        return KDRT_ERROR_INVALID_OPTION;
    if ((opt->allocator.alloc == NULL) != (opt->allocator.free == NULL))
        return KDRT_ERROR_NULL_ARGUMENT;
    return KDRT_SUCCESS;
}

/* The builder's settings from checked options, a zero option replaced by its default; the
   builder keeps pointers to opt and m, and its arrays start empty. */
static void kdrt__builder_init(kdrt__builder *b, const kdrt_build_options *opt,
                               const kdrt__meshes *m)
{
    memset(b, 0, sizeof *b);
    b->allocator = &opt->allocator;
    b->max_leaf_size = opt->max_leaf_size;
    b->mesh = m;
    b->sah_trav =
        opt->sah_traversal_cost > 0.0f ? opt->sah_traversal_cost : KDRT_DEFAULT_SAH_TRAVERSAL_COST;
    b->sah_isect = opt->sah_intersection_cost > 0.0f ? opt->sah_intersection_cost
                                                      : KDRT_DEFAULT_SAH_INTERSECTION_COST;
    b->sah_empty_bonus =
        opt->sah_empty_bonus > 0.0f ? opt->sah_empty_bonus : KDRT_DEFAULT_SAH_EMPTY_BONUS;
    b->max_depth = opt->max_depth ? opt->max_depth : kdrt__default_depth(m->triangles);
    if (b->max_depth > KDRT_MAX_DEPTH) b->max_depth = KDRT_MAX_DEPTH;
    b->sse = !(opt->flags & KDRT_BUILD_SCALAR_KERNEL);
    b->avx2 = b->sse && kdrt__cpu_has_avx2();
    switch (opt->quality) {
    case KDRT_BUILD_QUALITY_FAST:
        b->exact_max = 0, b->bins = KDRT__FAST_BINS, b->exact_fallback = 0, b->clip = 0;
        break;
    case KDRT_BUILD_QUALITY_HIGH:
        b->exact_max = KDRT__EVENT_REF_MASK, b->bins = KDRT_SAH_BINS, b->exact_fallback = 1;
        b->clip = 1;
        break;
    default:
        b->exact_max = KDRT_SAH_EXACT_MAX, b->bins = KDRT_SAH_BINS, b->exact_fallback = 1;
        b->clip = 1;
        break;
    }
}

/* An empty tree over the meshes (NULL: tree->one, for the caller to fill in), with no nodes
   yet; NULL when out of memory. */
static kdrt_tree *kdrt__tree_new(const kdrt_build_options *opt, const kdrt__meshes *m)
{
    kdrt_tree *tree = (kdrt_tree *)kdrt__alloc(&opt->allocator, sizeof *tree);
    uint32_t i;
    if (!tree) return NULL;
    memset(tree, 0, sizeof *tree);
    if (m) tree->meshes = *m;
    else tree->meshes.parts = &tree->one, tree->meshes.count = 1;
    tree->masks_full = 1;
    for (i = 0; m && i < m->count; ++i) tree->masks_full &= m->parts[i].mask == 0xFFFFFFFFu;
    tree->watertight = opt->intersector != KDRT_INTERSECTOR_FAST;
    if (opt->flags & KDRT_BUILD_SCALAR_KERNEL)
        tree->simd = KDRT_KERNEL_SCALAR;
    else if (kdrt__kernel_x4() != KDRT_KERNEL_SCALAR)
        tree->simd = (int)kdrt__kernel_x4();
    else if (!kdrt__cpu_has_avx2())
        tree->simd = KDRT_KERNEL_SCALAR;
    else if (!(opt->flags & KDRT_BUILD_AVX2_KERNEL) && kdrt__cpu_has_avx512())
        tree->simd = KDRT_KERNEL_AVX512;
    else
        tree->simd = KDRT_KERNEL_AVX2;
    tree->stats.kernel = (kdrt_kernel)tree->simd;
    /* Every AVX2 CPU made so far has FMA; checked all the same, once. */
    tree->closest_fma = (tree->simd == KDRT_KERNEL_AVX2 || tree->simd == KDRT_KERNEL_AVX512) &&
                        kdrt__cpu_has_fma();
    tree->allocator = opt->allocator;
    tree->bounds = kdrt_aabb_empty();
    tree->shape = *opt;
    tree->shape.flags &= (uint32_t)KDRT_BUILD_SKIP_INVALID_TRIANGLES;
    memset(&tree->shape.allocator, 0, sizeof tree->shape.allocator);
    memset(&tree->shape.scheduler, 0, sizeof tree->shape.scheduler);
    return tree;
}

/* Triangle preparation. Every triangle is checked: an invalid one fails the build, or under
   KDRT_BUILD_SKIP_INVALID_TRIANGLES is skipped, and a zero-area one is left out. The others get
   their box and centroid in b (by the caller's index), grow *bounds and are listed, in order, in
   (*valid)[0 .. *n). All of it is one allocation, *scratch, for the caller to free. With a
   scheduler the triangles are checked in KDRT__CHUNKS ranges as tasks (each triangle's verdict in
   b->side, each range's box), then listed in order: the same list and report either way. */
#define KDRT__TRIANGLE_VALID 0u
#define KDRT__TRIANGLE_DEGENERATE 1u
#define KDRT__TRIANGLE_INVALID 2u

typedef struct kdrt__preparing {
    kdrt__builder *b;
    const kdrt__meshes *m;
    float *boxes; /* b->lo, b->hi and b->centroid, writable */
    kdrt_aabb bounds[KDRT__CHUNKS];
    kdrt_result first_error[KDRT__CHUNKS]; /* each range's first invalid triangle's error */
} kdrt__preparing;

static void kdrt__prepare_range(void *data, uint32_t chunk)
{
    kdrt__preparing *p = (kdrt__preparing *)data;
    const size_t count = p->m->triangles;
    uint32_t tri, end = kdrt__chunk_start(p->m->triangles, chunk + 1u);
    float c[3][3];
    int a, k;
    p->bounds[chunk] = kdrt_aabb_empty();
    p->first_error[chunk] = KDRT_SUCCESS;
    for (tri = kdrt__chunk_start(p->m->triangles, chunk); tri < end; ++tri) {
        float *lo = p->boxes + 3 * (size_t)tri, *hi = lo + 3 * count, *centroid = hi + 3 * count;
        const kdrt__part *part = kdrt__part_of(p->m, tri);
        kdrt_result r = kdrt__check_triangle(&part->mesh, tri - part->first, c);
        if (r != KDRT_SUCCESS) {
            if (p->first_error[chunk] == KDRT_SUCCESS) p->first_error[chunk] = r;
            p->b->side[tri] = KDRT__TRIANGLE_INVALID;
            continue;
        }
        if (kdrt__zero_area(c)) {
            p->b->side[tri] = KDRT__TRIANGLE_DEGENERATE;
            continue;
        }
        p->b->side[tri] = KDRT__TRIANGLE_VALID;
        for (a = 0; a < 3; ++a) {
            lo[a] = hi[a] = c[0][a];
            for (k = 1; k < 3; ++k) {
                if (c[k][a] < lo[a]) lo[a] = c[k][a];
                if (c[k][a] > hi[a]) hi[a] = c[k][a];
            }
            /* Rounding can put the mean a hair outside the corners (a triangle in the plane
               x = 0.1 would get a centroid off that plane); keep it within them. */
            centroid[a] = (c[0][a] + c[1][a] + c[2][a]) * (1.0f / 3.0f);
            centroid[a] = centroid[a] < lo[a] ? lo[a] : (centroid[a] > hi[a] ? hi[a] : centroid[a]);
        }
        kdrt_aabb_grow(&p->bounds[chunk], lo);
        kdrt_aabb_grow(&p->bounds[chunk], hi);
    }
}

static kdrt_result kdrt__prepare_triangles(kdrt__builder *b, const kdrt__meshes *m,
                                           uint32_t flags, const kdrt_scheduler *scheduler,
                                           kdrt_aabb *bounds, float **scratch, uint32_t **valid,
                                           uint32_t *n, kdrt_build_report *report)
{
    const size_t count = m->triangles;
    kdrt__preparing p;
    uint32_t tri, skipped = 0, degenerate = 0, i;
    size_t bytes;

    *n = 0;
    /* Per triangle: box lo[3], hi[3] and centroid[3], then the list of usable triangles, then
       the builder's side marks (first each triangle's verdict). */
    if (!kdrt__mul_size(count, 9 * sizeof(float) + sizeof(uint32_t) + 1, &bytes))
        return KDRT_ERROR_SIZE_OVERFLOW;
    *scratch = (float *)kdrt__alloc(b->allocator, bytes);
    if (!*scratch) return KDRT_ERROR_OUT_OF_MEMORY;
    *valid = (uint32_t *)(*scratch + 9 * count);
    b->lo = *scratch;
    b->hi = *scratch + 3 * count;
    b->centroid = *scratch + 6 * count;
    b->side = (unsigned char *)(*valid + count);

    p.b = b, p.m = m, p.boxes = *scratch;
    if (scheduler && scheduler->run && count >= KDRT__CHUNK_MIN_REFS)
        scheduler->run(scheduler->user, kdrt__prepare_range, &p, KDRT__CHUNKS);
    else
        for (i = 0; i < KDRT__CHUNKS; ++i) kdrt__prepare_range(&p, i);
    for (i = 0; i < KDRT__CHUNKS; ++i)
        if (p.bounds[i].min[0] <= p.bounds[i].max[0]) { /* not empty */
            kdrt_aabb_grow(bounds, p.bounds[i].min);
            kdrt_aabb_grow(bounds, p.bounds[i].max);
        }
    for (tri = 0; tri < m->triangles; ++tri) {
        if (b->side[tri] == KDRT__TRIANGLE_INVALID) {
            if (report && report->invalid_triangle == KDRT_INVALID_ID)
                report->invalid_triangle = tri;
            if (!(flags & KDRT_BUILD_SKIP_INVALID_TRIANGLES)) {
                /* The first invalid triangle's error: the first range that has one. */
                for (i = 0; p.first_error[i] == KDRT_SUCCESS; ++i) continue;
                return p.first_error[i];
            }
            ++skipped;
        } else if (b->side[tri] == KDRT__TRIANGLE_DEGENERATE) {
            ++degenerate;
        } else {
            (*valid)[(*n)++] = tri;
        }
    }
    if (report) report->skipped_triangles = skipped, report->degenerate_triangles = degenerate;
    return KDRT_SUCCESS;
}

/* No tree (max_leaf_size 0, or nothing to build over): one leaf holding every usable triangle,
   tested in order. */
static kdrt_result kdrt__build_no_tree(kdrt__builder *b, const uint32_t *valid, uint32_t n)
{
    kdrt_result r =
        kdrt__reserve(b->allocator, (void **)&b->nodes, &b->node_capacity, 1, sizeof(kdrt__node));
    if (r != KDRT_SUCCESS) return r;
    b->node_count = 1;
    return kdrt__emit_leaf(b, 0, valid, n, 0);
}

/* The median builder: the triangles sorted once per axis by centroid; every node then filters
   its parent's lists. */
static kdrt_result kdrt__build_median(kdrt__builder *b, const uint32_t *valid, uint32_t n)
{
    uint32_t *lists = (uint32_t *)kdrt__alloc(b->allocator, 3 * (size_t)n * sizeof(uint32_t)), i;
    kdrt__key *keys = (kdrt__key *)kdrt__alloc(b->allocator, (size_t)n * sizeof(kdrt__key));
    kdrt_result r;
    int a;
    if (!lists || !keys) {
        kdrt__free(b->allocator, keys);
        kdrt__free(b->allocator, lists);
        return KDRT_ERROR_OUT_OF_MEMORY;
    }
    for (a = 0; a < 3; ++a) {
        for (i = 0; i < n; ++i)
            keys[i].key = b->centroid[3 * (size_t)valid[i] + (size_t)a], keys[i].tri = valid[i];
        qsort(keys, n, sizeof *keys, kdrt__key_less);
        for (i = 0; i < n; ++i) lists[(size_t)a * n + i] = keys[i].tri;
    }
    kdrt__free(b->allocator, keys);
    r = kdrt__build_node(b, lists, n, 0);
    kdrt__free(b->allocator, lists);
    return r;
}

/* The SAH builder, from a reference per usable triangle: its box. */
static kdrt_result kdrt__build_sah(kdrt__builder *b, const kdrt_scheduler *scheduler,
                                   const uint32_t *valid, uint32_t n, const kdrt_aabb *bounds)
{
    kdrt__ref *refs = (kdrt__ref *)kdrt__alloc(b->allocator, (size_t)n * sizeof(kdrt__ref));
    uint32_t i;
    if (!refs) return KDRT_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < n; ++i) {
        memcpy(refs[i].lo, b->lo + 3 * (size_t)valid[i], sizeof refs[i].lo);
        memcpy(refs[i].hi, b->hi + 3 * (size_t)valid[i], sizeof refs[i].hi);
        refs[i].tri = valid[i];
    }
    return kdrt__sah_build(b, scheduler, refs, n, bounds->min, bounds->max);
}

/* Dispatch: the nodes and leaf references into b, by the builder the options name. */
static kdrt_result kdrt__build_nodes(kdrt__builder *b, const kdrt_build_options *opt,
                                     const uint32_t *valid, uint32_t n, const kdrt_aabb *bounds)
{
    if (opt->max_leaf_size == 0 || n == 0) return kdrt__build_no_tree(b, valid, n);
    if (opt->builder == KDRT_BUILDER_SAH || opt->builder == KDRT_BUILDER_DEFAULT)
        return kdrt__build_sah(b, &opt->scheduler, valid, n, bounds);
    return kdrt__build_median(b, valid, n);
}

/* Stats: the builder's arrays, trimmed, go to the tree, and its statistics are filled in. */
static void kdrt__finish_tree(kdrt_tree *tree, kdrt__builder *b, uint32_t triangles)
{
    kdrt__shrink(b->allocator, (void **)&b->nodes, &b->node_capacity, b->node_count,
                 sizeof(kdrt__node));
    tree->nodes = b->nodes;
    b->nodes = NULL;
    tree->stats.triangles = triangles;
    tree->stats.nodes = b->node_count;
    tree->stats.leaves = b->leaves;
    tree->stats.max_depth = b->depth_reached;
    tree->stats.triangle_refs = b->ref_count;
    tree->stats.bytes = sizeof *tree + (size_t)b->node_capacity * sizeof(kdrt__node) +
                        (size_t)tree->stats.blocks * (sizeof(kdrt__block) + sizeof(uint32_t)) +
                        (tree->block_memory ? 63u : 0u);
    tree->stats.sah_cost = kdrt__sah_cost(tree, b->sah_trav, b->sah_isect);
}

/* ---- cells and ropes (START CELLS) ---- */

/* The node a rope across face (2 * axis + side) of the box [lo, hi] should name, from node, which
   covers the face: pushed down while one child's box still covers all of it (Havran's optimised
   ropes). */
static uint32_t kdrt__push_rope(const kdrt__node *nodes, uint32_t node, int face, const float lo[3],
                                const float hi[3])
{
    const uint32_t face_axis = (uint32_t)face >> 1;
    while (node != KDRT__NO_ROPE && !kdrt__node_is_leaf(&nodes[node])) {
        const kdrt__node *n = &nodes[node];
        const uint32_t axis = kdrt__node_axis(n);
        const float split = n->u.split;
        if (axis == face_axis) { /* the child on the face's side, if the plane is past it */
            if ((face & 1) && split > hi[axis]) node = node + 1;
            else if (!(face & 1) && split < lo[axis]) node = kdrt__node_above(n);
            else break;
        } else if (hi[axis] <= split)
            node = node + 1;
        else if (lo[axis] >= split)
            node = kdrt__node_above(n);
        else
            break; /* the plane cuts the face: both children share it */
    }
    return node;
}

/* The cells of node's subtree, whose box is [lo, hi] and whose faces' neighbours are rope[]. */
static void kdrt__cells_of(kdrt_tree *tree, uint32_t node, const float lo[3], const float hi[3],
                           const uint32_t rope[6], uint32_t *count)
{
    const kdrt__node *n = &tree->nodes[node];
    if (kdrt__node_is_leaf(n)) {
        kdrt__cell *c = &tree->cells[*count];
        int f;
        memcpy(c->lo, lo, sizeof c->lo), memcpy(c->hi, hi, sizeof c->hi);
        for (f = 0; f < 6; ++f) c->rope[f] = kdrt__push_rope(tree->nodes, rope[f], f, lo, hi);
        tree->cell_of[node] = (*count)++;
    } else {
        const uint32_t axis = kdrt__node_axis(n), above = kdrt__node_above(n);
        float clo[3], chi[3];
        uint32_t crope[6];
        tree->cell_of[node] = KDRT__NO_ROPE; /* defined, so that a saved tree's bytes are */
        memcpy(chi, hi, sizeof chi), memcpy(crope, rope, sizeof crope);
        chi[axis] = n->u.split, crope[2 * axis + 1] = above;
        kdrt__cells_of(tree, node + 1, lo, chi, crope, count);
        memcpy(clo, lo, sizeof clo), memcpy(crope, rope, sizeof crope);
        clo[axis] = n->u.split, crope[2 * axis] = node + 1;
        kdrt__cells_of(tree, above, clo, hi, crope, count);
    }
}

/* Every leaf's cell, and the map from nodes to cells; counted in stats.bytes. */
static kdrt_result kdrt__build_cells(kdrt_tree *tree)
{
    const uint32_t none[6] = {KDRT__NO_ROPE, KDRT__NO_ROPE, KDRT__NO_ROPE,
                              KDRT__NO_ROPE, KDRT__NO_ROPE, KDRT__NO_ROPE};
    uint32_t count = 0;
    if (tree->stats.nodes == 0) return KDRT_SUCCESS;
    tree->cells = (kdrt__cell *)kdrt__alloc(&tree->allocator,
                                           (size_t)tree->stats.leaves * sizeof(kdrt__cell));
    tree->cell_of = (uint32_t *)kdrt__alloc(&tree->allocator,
                                           (size_t)tree->stats.nodes * sizeof(uint32_t));
    if (!tree->cells || !tree->cell_of) return KDRT_ERROR_OUT_OF_MEMORY;
    kdrt__cells_of(tree, 0, tree->bounds.min, tree->bounds.max, none, &count);
    KDRT_ASSERT(count == tree->stats.leaves);
    tree->stats.bytes += (size_t)tree->stats.leaves * sizeof(kdrt__cell) +
                         (size_t)tree->stats.nodes * sizeof(uint32_t);
    return KDRT_SUCCESS;
}

/* Builds the nodes and blocks of a new tree over its meshes, with checked options; on failure
   frees the tree. */
static kdrt_result kdrt__build_tree(kdrt_tree *tree, const kdrt_build_options *opt,
                                    kdrt_build_report *report)
{
    kdrt__builder b;
    float *scratch = NULL;
    uint32_t *valid = NULL, n = 0;
    kdrt_result r;
    kdrt__builder_init(&b, opt, &tree->meshes);
    tree->depth_limit = b.max_depth;
    r = kdrt__prepare_triangles(&b, &tree->meshes, opt->flags, &opt->scheduler, &tree->bounds,
                                &scratch, &valid, &n, report);
    if (r == KDRT_SUCCESS) r = kdrt__build_nodes(&b, opt, valid, n, &tree->bounds);
    if (r == KDRT_SUCCESS)
        r = kdrt__pack_blocks(&opt->allocator, &opt->scheduler, &tree->meshes, b.nodes,
                              b.node_count, b.refs, tree);
    if (r == KDRT_SUCCESS) kdrt__finish_tree(tree, &b, n);
    if (r == KDRT_SUCCESS) r = kdrt__build_cells(tree);
    kdrt__free(&opt->allocator, scratch);
    kdrt__free(&opt->allocator, b.refs); /* the blocks hold the triangles now */
    if (r != KDRT_SUCCESS) {
        kdrt__free(&opt->allocator, b.nodes);
        kdrt_tree_free(tree); /* and the blocks packed so far */
    }
    return r;
}

/* A report with nothing found yet. */
static void kdrt__report_init(kdrt_build_report *report)
{
    if (!report) return;
    memset(report, 0, sizeof *report);
    report->invalid_triangle = report->invalid_geometry = KDRT_INVALID_ID;
}

KDRT_API kdrt_result kdrt_tree_build(const kdrt_triangles *mesh, const kdrt_build_options *options,
                                     kdrt_tree **out_tree, kdrt_build_report *report)
{
    kdrt_build_options opt = options ? *options : kdrt_default_build_options();
    kdrt_triangles m;
    kdrt_tree *tree;
    kdrt_result r;

    kdrt__report_init(report);
    if (!out_tree) return KDRT_ERROR_NULL_ARGUMENT;
    *out_tree = NULL;
    r = kdrt__check_view(mesh, &m);
    if (r == KDRT_SUCCESS) r = kdrt__check_options(&opt);
    if (r != KDRT_SUCCESS) return r;
    tree = kdrt__tree_new(&opt, NULL);
    if (!tree) return KDRT_ERROR_OUT_OF_MEMORY;
    tree->one.mesh = m, tree->one.mask = 0xFFFFFFFFu;
    tree->meshes.triangles = m.triangle_count;
    r = kdrt__build_tree(tree, &opt, report);
    if (r == KDRT_SUCCESS) *out_tree = tree;
    return r;
}

KDRT_API void kdrt_tree_free(kdrt_tree *tree)
{
    kdrt_allocator a;
    if (!tree) return;
    a = tree->allocator;
    if (!tree->in_place) {
        kdrt__free(&a, tree->nodes);
        kdrt__free(&a, tree->block_memory);
        kdrt__free(&a, tree->block_refs);
        kdrt__free(&a, tree->cells);
        kdrt__free(&a, tree->cell_of);
    }
    kdrt__free(&a, tree);
}

KDRT_API void kdrt_tree_get_stats(const kdrt_tree *tree, kdrt_tree_stats *out_stats)
{
    if (!out_stats) return;
    if (!tree) { memset(out_stats, 0, sizeof *out_stats); return; }
    *out_stats = tree->stats;
}

/* ==== inspection ==== */

KDRT_API uint32_t kdrt_tree_node_count(const kdrt_tree *tree)
{
    return tree ? tree->stats.nodes : 0u;
}

KDRT_API kdrt_result kdrt_tree_node(const kdrt_tree *tree, uint32_t index, kdrt_node_info *out_info)
{
    kdrt_node_info info;
    const kdrt__node *n;
    uint32_t at = 0;
    if (!tree || !out_info) return KDRT_ERROR_NULL_ARGUMENT;
    if (index >= tree->stats.nodes) return KDRT_ERROR_INDEX_OUT_OF_RANGE;
    memset(&info, 0, sizeof info);
    info.bounds = tree->bounds;
    /* Depth-first numbering: node index lies in the above child's subtree exactly when it is at
       or past the above child, else in the below child's. */
    while (at != index) {
        n = &tree->nodes[at];
        KDRT_ASSERT(!kdrt__node_is_leaf(n) && index > at);
        if (kdrt__node_is_leaf(n)) return KDRT_ERROR_INDEX_OUT_OF_RANGE; /* not reached */
        info.axis = (int)kdrt__node_axis(n);
        if (index >= kdrt__node_above(n)) {
            info.bounds.min[info.axis] = n->u.split;
            at = kdrt__node_above(n);
        } else {
            info.bounds.max[info.axis] = n->u.split;
            at += 1;
        }
        info.depth += 1;
    }
    n = &tree->nodes[index];
    if (kdrt__node_is_leaf(n)) {
        info.is_leaf = 1;
        info.axis = -1;
        info.below = info.above = KDRT_INVALID_ID;
        info.triangle_count = kdrt__node_count(n);
        /* An empty leaf has no block: its references would start where the next leaf's do. */
        info.first_reference = n->u.first < tree->stats.blocks ? tree->block_refs[n->u.first]
                                                               : (uint32_t)tree->stats.triangle_refs;
        memcpy(info.ropes, tree->cells[tree->cell_of[index]].rope, sizeof info.ropes);
    } else {
        memset(info.ropes, 0xFF, sizeof info.ropes); /* KDRT_INVALID_ID */
        info.axis = (int)kdrt__node_axis(n);
        info.split = n->u.split;
        info.below = index + 1u;
        info.above = kdrt__node_above(n);
    }
    *out_info = info;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_tree_reference(const kdrt_tree *tree, uint32_t reference,
                                         uint32_t *out_triangle)
{
    uint32_t lo = 0, hi;
    if (!tree || !out_triangle) return KDRT_ERROR_NULL_ARGUMENT;
    if ((uint64_t)reference >= tree->stats.triangle_refs) return KDRT_ERROR_INDEX_OUT_OF_RANGE;
    /* The last block starting at or before it; block_refs ascends. */
    hi = tree->stats.blocks - 1u;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo + 1u) / 2u;
        if (tree->block_refs[mid] <= reference) lo = mid;
        else hi = mid - 1u;
    }
    *out_triangle = tree->blocks[lo].id[reference - tree->block_refs[lo]];
    return KDRT_SUCCESS;
}

KDRT_API kdrt_aabb kdrt_tree_bounds(const kdrt_tree *tree)
{
    return tree ? tree->bounds : kdrt_aabb_empty();
}

/* ==== intersection tests ==== */

/* A candidate on the tree's triangle number tri as the caller knows it: its geometry's ID, the
   instance's, and its index within its mesh; returns the mesh's part. */
static const kdrt__part *kdrt__name_hit(const kdrt__rules *r, uint32_t tri, kdrt_hit *hit)
{
    const kdrt__part *part = kdrt__part_of(r->meshes, tri);
    hit->triangle = tri - part->first;
    hit->geometry = r->instance != KDRT_INVALID_ID ? r->instance : part->id;
    hit->instance = r->instance;
    return part;
}

/* A miss, as the queries report it. */
static void kdrt__miss(kdrt_hit *hit)
{
    hit->t = hit->u = hit->v = 0.0f;
    hit->triangle = KDRT_INVALID_ID, hit->geometry = 0, hit->instance = KDRT_INVALID_ID;
    hit->cell = 0;
}

/* A walk's bound: t, or a full list's last hit when that is nearer (list may be NULL). */
static float kdrt__list_bound(const kdrt__hit_list *list, float t)
{
    if (!list || list->count < list->capacity) return t;
    return list->hits[list->count - 1u].t < t ? list->hits[list->count - 1u].t : t;
}

/* The scene's order of hits: t, then geometry ID, then triangle. */
static int kdrt__hit_before(const kdrt_hit *a, const kdrt_hit *b)
{
    if (a->t != b->t) return a->t < b->t;
    if (a->geometry != b->geometry) return a->geometry < b->geometry;
    return a->triangle < b->triangle;
}

/* kdrt_intersect_k: a hit before the bound goes into the list, in order, once per triangle (one
   split across leaves is met again, with the same answer). While the list has room the bound is
   the ray's tmax; once it is full, the bound is its last hit, so the traversal skips whatever
   lies beyond, as it does beyond the nearest hit. One list may take the hits of several walks
   (a scene's meshes and instances): they are named, and ordered, as the caller knows them. */
static int kdrt__keep_hit(kdrt__hit_list *list, kdrt_hit *bound, const kdrt_hit *hit)
{
    uint32_t i;
    for (i = 0; i < list->count; ++i)
        if (list->hits[i].triangle == hit->triangle && list->hits[i].geometry == hit->geometry)
            return 0;
    /* Full: the new hit must come before the last, which drops out. */
    if (list->count == list->capacity && !kdrt__hit_before(hit, &list->hits[list->count - 1u]))
        return 0;
    i = list->count < list->capacity ? list->count : list->capacity - 1u;
    for (; i > 0 && kdrt__hit_before(hit, &list->hits[i - 1]); --i)
        list->hits[i] = list->hits[i - 1];
    list->hits[i] = *hit;
    if (list->count < list->capacity) ++list->count;
    if (list->count == list->capacity) bound->t = list->hits[list->count - 1u].t;
    return 1;
}

/* Whether the rules count the candidate (named, on the mesh part): its geometry seen by the
   ray's mask, its face not culled, and its filter says yes. */
static int kdrt__counts(const kdrt__rules *r, const kdrt__part *part, const kdrt_hit *candidate,
                        int front)
{
    if (r->test_mask && !(part->mask & r->mask)) return 0;
    if (r->flags & (front ? KDRT_QUERY_CULL_FRONT_FACES : KDRT_QUERY_CULL_BACK_FACES)) return 0;
    return !r->filter || r->filter(r->user, r->ray, candidate) != 0;
}

/* Both triangle tests accept t in [tmin, best->t], equal t going to the lower triangle index so
   that the answer does not depend on the order of the tests: whether a candidate hit on triangle
   tri is nearer than best (or as near, on a lower triangle) and usable. */
static int kdrt__nearer(const kdrt_hit *best, uint32_t tri, float t, float u, float v,
                        const kdrt__ray_setup *s)
{
    if (!(t >= s->tmin && t <= best->t)) return 0;
    /* A distance or barycentric past float's range (a ray all but in the triangle's plane, or a
       fast test's product overflowing) is no hit anyone can use. */
    if (!kdrt__finite(t) || !kdrt__finite(u) || !kdrt__finite(v)) return 0;
    return !(t == best->t && tri > best->triangle);
}

/* A candidate hit, taken when nearer: the plain queries' (no kdrt_query rules, no list). */
static int kdrt__accept(kdrt_hit *best, uint32_t tri, float t, float u, float v,
                        const kdrt__ray_setup *s)
{
    if (!kdrt__nearer(best, tri, t, u, v, s)) return 0;
    best->t = t, best->u = u, best->v = v, best->triangle = tri;
    return 1;
}

/* A candidate hit under a query's rules or into kdrt_intersect_k's list: taken when nearer and
   counted. front: whether the ray hits the triangle's front face (kdrt_query_flags), from the
   sign of the test's own determinant. Out of line: the plain queries never call it, and inlined
   into the walk it slowed their primary rays by a quarter. */
#if defined(__GNUC__) || defined(__clang__)
#define KDRT__NOINLINE __attribute__((noinline))
#elif defined(_MSC_VER)
#define KDRT__NOINLINE __declspec(noinline)
#else
#define KDRT__NOINLINE
#endif
KDRT__NOINLINE static int kdrt__accept_ruled(kdrt_hit *best, uint32_t tri, float t, float u,
                                             float v, int front, const kdrt__ray_setup *s)
{
    kdrt_hit candidate;
    /* A list orders by the named hit (kdrt__keep_hit); the nearest hit by the tree's number. */
    if (s->list ? !kdrt__nearer(best, 0u, t, u, v, s) : !kdrt__nearer(best, tri, t, u, v, s))
        return 0;
    candidate.t = t, candidate.u = u, candidate.v = v, candidate.cell = 0;
    if (!kdrt__counts(s->rules, kdrt__name_hit(s->rules, tri, &candidate), &candidate, front))
        return 0;
    if (s->list) return kdrt__keep_hit(s->list, best, &candidate);
    best->t = t, best->u = u, best->v = v, best->triangle = tri;
    return 1;
}

/* The corners of a block's lane: p[k][a] = coordinate a of corner k. */
static void kdrt__lane_corners(const kdrt__block *block, uint32_t lane, float p[3][3])
{
    int k, a;
    for (k = 0; k < 3; ++k)
        for (a = 0; a < 3; ++a) p[k][a] = block->corner[3 * k + a][lane];
}

/* Watertight test (Woop, Benthin & Wald, JCGT 2013). The corners are moved to the ray's origin
   and sheared so the ray runs along +z; the 2D edge functions then depend only on the two corners
   of each edge, so triangles sharing that edge compute it with the same value and opposite sign,
   and a ray through the edge or a shared vertex hits at least one of them. The AVX2 kernel's
   kdrt__block_watertight_avx2 is the same arithmetic, operation for operation. */
static int kdrt__intersect_watertight(const kdrt__block *block, uint32_t lane,
                                      const kdrt__ray_setup *s, kdrt_hit *best, int ruled)
{
    float p[3][3], x[3], y[3], z[3], t, u, v;
    double e0, e1, e2, det, inv_det;
    const int kx = s->kx, ky = s->ky, kz = s->kz;
    int k;
    kdrt__lane_corners(block, lane, p);
    for (k = 0; k < 3; ++k) {
        float dx = p[k][kx] - s->org[kx], dy = p[k][ky] - s->org[ky], dz = p[k][kz] - s->org[kz];
        x[k] = dx - s->shear_x * dz;
        y[k] = dy - s->shear_y * dz;
        z[k] = s->shear_z * dz;
    }
    /* In double the products of floats are exact, so each edge function is rounded once and its
       sign is right: the two triangles of an edge get exactly opposite values, even where the
       compiler fuses a * b - c * d into an FMA (-march=native, Clang's default on ARM). Kept in
       double, they neither overflow nor turn subnormal however large or small the coordinates
       (a float edge function overflows beyond about 1e19 and loses its bits below 1e-19).
       Written out rather than with kdrt__cross: each is a 2D determinant of floats. */
    e0 = (double)x[2] * y[1] - (double)y[2] * x[1]; /* edge 1-2: weight of corner 0 */
    e1 = (double)x[0] * y[2] - (double)y[0] * x[2]; /* edge 2-0: weight of corner 1 */
    e2 = (double)x[1] * y[0] - (double)y[1] * x[0]; /* edge 0-1: weight of corner 2 */
    if ((e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0)) return 0;
    det = e0 + e1 + e2;
    if (det == 0.0) return 0; /* the ray lies in the triangle's plane, sheared exactly */
    inv_det = 1.0 / det;
    t = (float)((e0 * z[0] + e1 * z[1] + e2 * z[2]) * inv_det);
    u = (float)(e1 * inv_det), v = (float)(e2 * inv_det);
    return ruled ? kdrt__accept_ruled(best, block->id[lane], t, u, v, det > 0.0, s)
                 : kdrt__accept(best, block->id[lane], t, u, v, s);
}

/* Moeller-Trumbore, no epsilon: fewer operations, but the edge tests of two triangles sharing an
   edge are computed differently, so a ray through the edge can miss both. The AVX2 kernel's
   kdrt__block_fast_avx2 is the same arithmetic, operation for operation. */
static int kdrt__intersect_fast(const kdrt__block *block, uint32_t lane, const kdrt__ray_setup *s,
                                kdrt_hit *best, int ruled)
{
    float p[3][3], e1[3], e2[3], pv[3], tv[3], qv[3], det, inv_det, u, v, t;
    int a;
    kdrt__lane_corners(block, lane, p);
    for (a = 0; a < 3; ++a)
        e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a], tv[a] = s->org[a] - p[0][a];
    kdrt__cross_float(s->dir, e2, pv);
    det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0.0f) return 0; /* parallel to the plane */
    inv_det = 1.0f / det;
    u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) * inv_det;
    if (!(u >= 0.0f && u <= 1.0f)) return 0;
    kdrt__cross_float(tv, e1, qv);
    v = (s->dir[0] * qv[0] + s->dir[1] * qv[1] + s->dir[2] * qv[2]) * inv_det;
    if (!(v >= 0.0f && u + v <= 1.0f)) return 0;
    t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) * inv_det;
    /* det = e1 . (dir x e2) = -dir . (e1 x e2): positive on the front face */
    return ruled ? kdrt__accept_ruled(best, block->id[lane], t, u, v, det > 0.0f, s)
                 : kdrt__accept(best, block->id[lane], t, u, v, s);
}

/* Inlined where a walk's speed depends on it: the plain queries are the walk without rules,
   as fast as before rules existed, only if their constant arguments reach it. */
#if defined(__GNUC__) || defined(__clang__)
#define KDRT__FORCEINLINE __attribute__((always_inline)) inline
#elif defined(_MSC_VER)
#define KDRT__FORCEINLINE __forceinline
#else
#define KDRT__FORCEINLINE
#endif

/* ==== the SIMD kernels: which one this build compiles, and what they share ==== */

/* Which SIMD kernel this build compiles, the AVX2 target attribute and the CPU check are
   defined with SSE2, above the builder, which uses them too. */

/* The lowest set bit of bits (not 0). */
#if defined(_MSC_VER)
#include <intrin.h> /* _BitScanForward */
static KDRT__FORCEINLINE unsigned kdrt__ctz(unsigned bits)
{
    unsigned long index;
    _BitScanForward(&index, bits);
    return (unsigned)index;
}
#elif defined(__GNUC__) || defined(__clang__)
static KDRT__FORCEINLINE unsigned kdrt__ctz(unsigned bits) { return (unsigned)__builtin_ctz(bits); }
#else
static unsigned kdrt__ctz(unsigned bits)
{
    unsigned index = 0;
    for (; !(bits & 1u); bits >>= 1) ++index;
    return index;
}
#endif

#if defined(KDRT__AVX2) || defined(KDRT__X4)

/* What a block test found: the lanes whose triangles the ray meets (its return value, a bit a
   lane), their t, u, v, and front, a bit a lane set where the ray meets the front face. The block
   tests only find; the traversal decides (kdrt__accept_lanes), so that the tests, which most
   blocks leave early, make no calls and save no registers. A lane is a block's triangle, or a
   packet's ray (up to KDRT__PACKET_MAX of them). */
#define KDRT__PACKET_MAX 16u
typedef struct kdrt__candidates {
    float t[KDRT__PACKET_MAX], u[KDRT__PACKET_MAX], v[KDRT__PACKET_MAX];
    unsigned front;
} kdrt__candidates;

/* The lanes of mask offered to kdrt__accept in turn: the order does not matter, as kdrt__accept
   keeps the lowest (t, triangle) whatever the order it is offered them. ruled: s has a query's
   rules or a list (kdrt__accept_ruled). */
static int kdrt__accept_lanes(kdrt_hit *best, const kdrt__block *block, unsigned mask,
                              const kdrt__candidates *c, const kdrt__ray_setup *s, int ruled)
{
    int found = 0;
    for (; mask; mask &= mask - 1u) {
        const unsigned lane = kdrt__ctz(mask), id = block->id[lane];
        found |= ruled
                     ? kdrt__accept_ruled(best, id, c->t[lane], c->u[lane], c->v[lane],
                                          (int)((c->front >> lane) & 1u), s)
                     : kdrt__accept(best, id, c->t[lane], c->u[lane], c->v[lane], s);
    }
    return found;
}

#endif

/* ==== the AVX2 kernel: 8 triangles at a time ==== */

/* Compiled with the compiler's per-function target attribute (GCC, Clang, clang-cl), so no -mavx2
   is needed, or on MSVC, whose intrinsics need no flag, with none; chosen when a tree is built if
   the CPU has AVX2 (kdrt__cpu_has_avx2). Not where KDRT_NO_SIMD is defined, nor off x86-64. The
   target is "avx2" alone, not FMA: without FMA instructions the compiler cannot fuse a multiply
   and an add, so each operation rounds as the scalar kernel's does and the answers are the same
   bit for bit. */
#if defined(KDRT__AVX2)
/* kdrt__surely_missed_avx2 and kdrt__watertight_lanes_avx2: the exact test on 8 lanes, written
   once for 8 and 16 (PACKETS, at the end of this file). */
#define KDRT__PACKET_WIDTH 8
#define KDRT__PACKET_PARTS 1
#include KDRT_HEADER_FILENAME
#undef KDRT__PACKET_WIDTH
#undef KDRT__PACKET_PARTS

/* kdrt__intersect_watertight on a block's 8 lanes. */
KDRT__TARGET_AVX2 static unsigned kdrt__block_watertight_avx2(const kdrt__block *block,
                                                              const kdrt__ray_setup *s,
                                                              kdrt__candidates *c)
{
    const int kx = s->kx, ky = s->ky, kz = s->kz;
    const __m256 ox = _mm256_set1_ps(s->org[kx]), oy = _mm256_set1_ps(s->org[ky]);
    const __m256 oz = _mm256_set1_ps(s->org[kz]);
    const __m256 sx = _mm256_set1_ps(s->shear_x), sy = _mm256_set1_ps(s->shear_y);
    const __m256 sz = _mm256_set1_ps(s->shear_z);
    __m256 fx[3], fy[3], fz[3];
    int k;
    for (k = 0; k < 3; ++k) {
        const __m256 dx = _mm256_sub_ps(_mm256_load_ps(block->corner[3 * k + kx]), ox);
        const __m256 dy = _mm256_sub_ps(_mm256_load_ps(block->corner[3 * k + ky]), oy);
        const __m256 dz = _mm256_sub_ps(_mm256_load_ps(block->corner[3 * k + kz]), oz);
        fx[k] = _mm256_sub_ps(dx, _mm256_mul_ps(sx, dz));
        fy[k] = _mm256_sub_ps(dy, _mm256_mul_ps(sy, dz));
        fz[k] = _mm256_mul_ps(sz, dz);
    }
    return kdrt__watertight_lanes_avx2(fx, fy, fz, 0xFFu, c);
}

/* kdrt__intersect_fast on a block's 8 lanes. */
KDRT__TARGET_AVX2 static unsigned kdrt__block_fast_avx2(const kdrt__block *block,
                                                        const kdrt__ray_setup *s,
                                                        kdrt__candidates *c)
{
    __m256 p0[3], e1[3], e2[3], tv[3], d[3], pv[3], qv[3], det, inv_det, u, v, t, keep;
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
    unsigned mask;
    int a;
    for (a = 0; a < 3; ++a) {
        p0[a] = _mm256_load_ps(block->corner[a]);
        e1[a] = _mm256_sub_ps(_mm256_load_ps(block->corner[3 + a]), p0[a]);
        e2[a] = _mm256_sub_ps(_mm256_load_ps(block->corner[6 + a]), p0[a]);
        tv[a] = _mm256_sub_ps(_mm256_set1_ps(s->org[a]), p0[a]);
        d[a] = _mm256_set1_ps(s->dir[a]);
    }
#define KDRT__CROSS(a, b, c)                                                                   \
    (c[0] = _mm256_sub_ps(_mm256_mul_ps(a[1], b[2]), _mm256_mul_ps(a[2], b[1])),               \
     c[1] = _mm256_sub_ps(_mm256_mul_ps(a[2], b[0]), _mm256_mul_ps(a[0], b[2])),               \
     c[2] = _mm256_sub_ps(_mm256_mul_ps(a[0], b[1]), _mm256_mul_ps(a[1], b[0])))
#define KDRT__DOT(a, b)                                                                        \
    _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),          \
                  _mm256_mul_ps(a[2], b[2]))
    KDRT__CROSS(d, e2, pv);
    det = KDRT__DOT(e1, pv);
    inv_det = _mm256_div_ps(one, det);
    u = _mm256_mul_ps(KDRT__DOT(tv, pv), inv_det);
    KDRT__CROSS(tv, e1, qv);
    v = _mm256_mul_ps(KDRT__DOT(d, qv), inv_det);
    t = _mm256_mul_ps(KDRT__DOT(e2, qv), inv_det);
#undef KDRT__CROSS
#undef KDRT__DOT
    keep = _mm256_and_ps(_mm256_cmp_ps(det, zero, _CMP_NEQ_UQ),
                         _mm256_and_ps(_mm256_cmp_ps(u, zero, _CMP_GE_OQ), _mm256_cmp_ps(u, one, _CMP_LE_OQ)));
    keep = _mm256_and_ps(keep, _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_GE_OQ),
                                             _mm256_cmp_ps(_mm256_add_ps(u, v), one, _CMP_LE_OQ)));
    mask = (unsigned)_mm256_movemask_ps(keep);
    if (!mask) return 0;
    _mm256_storeu_ps(c->t, t), _mm256_storeu_ps(c->u, u), _mm256_storeu_ps(c->v, v);
    c->front = (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(det, zero, _CMP_GT_OQ));
    return mask;
}
#endif

/* ==== the 4-wide kernel: NEON and WebAssembly SIMD128, a block as two halves of 4 ==== */

/* On aarch64, where NEON is part of the architecture (so it is chosen at compile time, with no CPU
   check), and on WebAssembly compiled with SIMD128 (emcc -msimd128). Its block tests are the
   scalar tests' arithmetic, operation for operation, on 4 lanes at a time: a block's 8 lanes as
   two halves, the watertight test's doubles 2 at a time. They are written once over the
   kdrt__x4 operations below, which each instruction set defines. No multiply is fused with the
   add that reads it, whatever -ffp-contract says: on NEON each product passes through an empty
   asm statement, which hides where the value came from (GCC and Clang would otherwise fuse
   vmulq and vaddq into fmla), and SIMD128 has no fused multiply-add. Batches walk their rays one
   at a time on this kernel (kdrt__batch). Never beside the AVX2 kernel: one architecture each. */
#if defined(KDRT__X4)

#if defined(__aarch64__)
#include <arm_neon.h>
#define KDRT__X4_KERNEL KDRT_KERNEL_NEON
typedef float32x4_t kdrt__x4;  /* 4 floats */
typedef uint32x4_t kdrt__x4m;  /* 4 lanes' truth: all bits set or clear */
typedef float64x2_t kdrt__x2d; /* 2 doubles */
typedef uint64x2_t kdrt__x2dm; /* 2 lanes' truth */
static KDRT__FORCEINLINE float32x4_t kdrt__x4_mul(float32x4_t a, float32x4_t b)
{
    float32x4_t product = vmulq_f32(a, b);
    __asm__("" : "+w"(product)); /* not fused into the add that reads it (see above) */
    return product;
}
static KDRT__FORCEINLINE float64x2_t kdrt__x2d_mul(float64x2_t a, float64x2_t b)
{
    float64x2_t product = vmulq_f64(a, b);
    __asm__("" : "+w"(product));
    return product;
}
static KDRT__FORCEINLINE unsigned kdrt__x4m_bits(uint32x4_t m)
{
    const uint32_t bit[4] = {1u, 2u, 4u, 8u};
    return vaddvq_u32(vandq_u32(m, vld1q_u32(bit)));
}
static KDRT__FORCEINLINE unsigned kdrt__x2dm_bits(uint64x2_t m)
{
    const uint64_t bit[2] = {1u, 2u};
    return (unsigned)vaddvq_u64(vandq_u64(m, vld1q_u64(bit)));
}
#define kdrt__x4_load(p) vld1q_f32(p)
#define kdrt__x4_store(p, x) vst1q_f32(p, x)
#define kdrt__x4_set1(x) vdupq_n_f32(x)
#define kdrt__x4_add(a, b) vaddq_f32(a, b)
#define kdrt__x4_sub(a, b) vsubq_f32(a, b)
#define kdrt__x4_div(a, b) vdivq_f32(a, b)
#define kdrt__x4_lt(a, b) vcltq_f32(a, b)
#define kdrt__x4_gt(a, b) vcgtq_f32(a, b)
#define kdrt__x4_le(a, b) vcleq_f32(a, b)
#define kdrt__x4_ge(a, b) vcgeq_f32(a, b)
#define kdrt__x4_ne(a, b) vmvnq_u32(vceqq_f32(a, b)) /* true for NaN, as C's != */
#define kdrt__x4m_and(a, b) vandq_u32(a, b)
#define kdrt__x4m_or(a, b) vorrq_u32(a, b)
#define kdrt__x2d_set1(x) vdupq_n_f64(x)
#define kdrt__x2d_add(a, b) vaddq_f64(a, b)
#define kdrt__x2d_sub(a, b) vsubq_f64(a, b)
#define kdrt__x2d_div(a, b) vdivq_f64(a, b)
#define kdrt__x2d_lt(a, b) vcltq_f64(a, b)
#define kdrt__x2d_gt(a, b) vcgtq_f64(a, b)
#define kdrt__x2d_ne(a, b) vreinterpretq_u64_u32(vmvnq_u32(vreinterpretq_u32_u64(vceqq_f64(a, b))))
#define kdrt__x2dm_and(a, b) vandq_u64(a, b)
#define kdrt__x2dm_or(a, b) vorrq_u64(a, b)
#define kdrt__x2dm_andnot(a, b) vbicq_u64(b, a) /* b and not a */
#define kdrt__x2d_widen(x, half) /* the floats of half 0 or 1 of x, exact */                      \
    ((half) ? vcvt_high_f64_f32(x) : vcvt_f64_f32(vget_low_f32(x)))
#define kdrt__x4_narrow(lo, hi) vcvt_high_f32_f64(vcvt_f32_f64(lo), hi) /* each rounded once */

#else /* __wasm_simd128__ */
#include <wasm_simd128.h>
#define KDRT__X4_KERNEL KDRT_KERNEL_SIMD128
typedef v128_t kdrt__x4;
typedef v128_t kdrt__x4m;
typedef v128_t kdrt__x2d;
typedef v128_t kdrt__x2dm;
#define kdrt__x4_mul(a, b) wasm_f32x4_mul(a, b)
#define kdrt__x2d_mul(a, b) wasm_f64x2_mul(a, b)
#define kdrt__x4m_bits(m) ((unsigned)wasm_i32x4_bitmask(m))
#define kdrt__x2dm_bits(m) ((unsigned)wasm_i64x2_bitmask(m))
#define kdrt__x4_load(p) wasm_v128_load(p)
#define kdrt__x4_store(p, x) wasm_v128_store(p, x)
#define kdrt__x4_set1(x) wasm_f32x4_splat(x)
#define kdrt__x4_add(a, b) wasm_f32x4_add(a, b)
#define kdrt__x4_sub(a, b) wasm_f32x4_sub(a, b)
#define kdrt__x4_div(a, b) wasm_f32x4_div(a, b)
#define kdrt__x4_lt(a, b) wasm_f32x4_lt(a, b)
#define kdrt__x4_gt(a, b) wasm_f32x4_gt(a, b)
#define kdrt__x4_le(a, b) wasm_f32x4_le(a, b)
#define kdrt__x4_ge(a, b) wasm_f32x4_ge(a, b)
#define kdrt__x4_ne(a, b) wasm_f32x4_ne(a, b) /* true for NaN, as C's != */
#define kdrt__x4m_and(a, b) wasm_v128_and(a, b)
#define kdrt__x4m_or(a, b) wasm_v128_or(a, b)
#define kdrt__x2d_set1(x) wasm_f64x2_splat(x)
#define kdrt__x2d_add(a, b) wasm_f64x2_add(a, b)
#define kdrt__x2d_sub(a, b) wasm_f64x2_sub(a, b)
#define kdrt__x2d_div(a, b) wasm_f64x2_div(a, b)
#define kdrt__x2d_lt(a, b) wasm_f64x2_lt(a, b)
#define kdrt__x2d_gt(a, b) wasm_f64x2_gt(a, b)
#define kdrt__x2d_ne(a, b) wasm_f64x2_ne(a, b)
#define kdrt__x2dm_and(a, b) wasm_v128_and(a, b)
#define kdrt__x2dm_or(a, b) wasm_v128_or(a, b)
#define kdrt__x2dm_andnot(a, b) wasm_v128_andnot(b, a) /* b and not a */
#define kdrt__x2d_widen(x, half)                                                                  \
    wasm_f64x2_promote_low_f32x4((half) ? wasm_i32x4_shuffle(x, x, 2, 3, 2, 3) : (x))
#define kdrt__x4_narrow(lo, hi)                                                                   \
    wasm_i64x2_shuffle(wasm_f32x4_demote_f64x2_zero(lo), wasm_f32x4_demote_f64x2_zero(hi), 0, 2)
#endif

static kdrt_kernel kdrt__kernel_x4(void) { return KDRT__X4_KERNEL; }

/* kdrt__intersect_watertight on the block's lanes first .. first + 3 (first 0 or 4): the lanes
   it finds as bits 0 to 3, their t, u, v in c from lane first on, their front faces added to
   c->front. */
static KDRT__FORCEINLINE unsigned kdrt__watertight_x4(const kdrt__block *block, unsigned first,
                                                      const kdrt__ray_setup *s,
                                                      kdrt__candidates *c)
{
    const int kx = s->kx, ky = s->ky, kz = s->kz;
    const kdrt__x4 ox = kdrt__x4_set1(s->org[kx]), oy = kdrt__x4_set1(s->org[ky]);
    const kdrt__x4 oz = kdrt__x4_set1(s->org[kz]);
    const kdrt__x4 sx = kdrt__x4_set1(s->shear_x), sy = kdrt__x4_set1(s->shear_y);
    const kdrt__x4 sz = kdrt__x4_set1(s->shear_z);
    const kdrt__x2d zero = kdrt__x2d_set1(0.0);
    kdrt__x4 x[3], y[3], z[3];
    kdrt__x4m neg, pos, lt, gt;
    kdrt__x2d e0[2], e1[2], e2[2], det[2], t[2], u[2], v[2];
    unsigned mask = 0, h;
    int k;
    for (k = 0; k < 3; ++k) {
        const kdrt__x4 dx = kdrt__x4_sub(kdrt__x4_load(block->corner[3 * k + kx] + first), ox);
        const kdrt__x4 dy = kdrt__x4_sub(kdrt__x4_load(block->corner[3 * k + ky] + first), oy);
        const kdrt__x4 dz = kdrt__x4_sub(kdrt__x4_load(block->corner[3 * k + kz] + first), oz);
        x[k] = kdrt__x4_sub(dx, kdrt__x4_mul(sx, dz));
        y[k] = kdrt__x4_sub(dy, kdrt__x4_mul(sy, dz));
        z[k] = kdrt__x4_mul(sz, dz);
    }
    /* The AVX2 kernel's filter (kdrt__surely_missed): float products that already order an edge
       function's two terms prove its sign; lanes with edge functions of both signs are missed. */
    for (k = 0; k < 3; ++k) {
        const int i = (k + 2) % 3, j = (k + 1) % 3; /* edge j-i, weight of corner k */
        const kdrt__x4 a = kdrt__x4_mul(x[i], y[j]), b = kdrt__x4_mul(y[i], x[j]);
        lt = kdrt__x4_lt(a, b), gt = kdrt__x4_gt(a, b);
        neg = k ? kdrt__x4m_or(neg, lt) : lt;
        pos = k ? kdrt__x4m_or(pos, gt) : gt;
    }
    if (kdrt__x4m_bits(kdrt__x4m_and(neg, pos)) == 0xFu) return 0;
    /* The exact edge functions, in double, two lanes at a time. */
    for (h = 0; h < 2u; ++h) {
        kdrt__x2d xd[3], yd[3];
        kdrt__x2dm negd, posd;
        for (k = 0; k < 3; ++k) xd[k] = kdrt__x2d_widen(x[k], h), yd[k] = kdrt__x2d_widen(y[k], h);
        e0[h] = kdrt__x2d_sub(kdrt__x2d_mul(xd[2], yd[1]), kdrt__x2d_mul(yd[2], xd[1]));
        e1[h] = kdrt__x2d_sub(kdrt__x2d_mul(xd[0], yd[2]), kdrt__x2d_mul(yd[0], xd[2]));
        e2[h] = kdrt__x2d_sub(kdrt__x2d_mul(xd[1], yd[0]), kdrt__x2d_mul(yd[1], xd[0]));
        negd = kdrt__x2dm_or(kdrt__x2dm_or(kdrt__x2d_lt(e0[h], zero), kdrt__x2d_lt(e1[h], zero)),
                             kdrt__x2d_lt(e2[h], zero));
        posd = kdrt__x2dm_or(kdrt__x2dm_or(kdrt__x2d_gt(e0[h], zero), kdrt__x2d_gt(e1[h], zero)),
                             kdrt__x2d_gt(e2[h], zero));
        det[h] = kdrt__x2d_add(kdrt__x2d_add(e0[h], e1[h]), e2[h]);
        /* not (negative and positive), and det != 0 (NaN goes on, as in C) */
        mask |= kdrt__x2dm_bits(kdrt__x2dm_andnot(kdrt__x2dm_and(negd, posd),
                                                  kdrt__x2d_ne(det[h], zero)))
                << (2u * h);
    }
    if (!mask) return 0; /* most blocks: no lane's triangle contains the ray */
    for (h = 0; h < 2u; ++h) {
        const kdrt__x2d inv_det = kdrt__x2d_div(kdrt__x2d_set1(1.0), det[h]);
        const kdrt__x2d num = kdrt__x2d_add(
            kdrt__x2d_add(kdrt__x2d_mul(e0[h], kdrt__x2d_widen(z[0], h)),
                          kdrt__x2d_mul(e1[h], kdrt__x2d_widen(z[1], h))),
            kdrt__x2d_mul(e2[h], kdrt__x2d_widen(z[2], h)));
        c->front |= kdrt__x2dm_bits(kdrt__x2d_gt(det[h], zero)) << (first + 2u * h);
        t[h] = kdrt__x2d_mul(num, inv_det);
        u[h] = kdrt__x2d_mul(e1[h], inv_det), v[h] = kdrt__x2d_mul(e2[h], inv_det);
    }
    kdrt__x4_store(c->t + first, kdrt__x4_narrow(t[0], t[1]));
    kdrt__x4_store(c->u + first, kdrt__x4_narrow(u[0], u[1]));
    kdrt__x4_store(c->v + first, kdrt__x4_narrow(v[0], v[1]));
    return mask;
}

/* kdrt__intersect_watertight on a block's 8 lanes: what kdrt__block_watertight_avx2 finds. */
static unsigned kdrt__block_watertight_x4(const kdrt__block *block, const kdrt__ray_setup *s,
                                          kdrt__candidates *c)
{
    c->front = 0;
    return kdrt__watertight_x4(block, 0, s, c) | kdrt__watertight_x4(block, 4, s, c) << 4;
}

/* kdrt__intersect_fast on the block's lanes first .. first + 3, found as kdrt__watertight_x4
   finds. */
static KDRT__FORCEINLINE unsigned kdrt__fast_x4(const kdrt__block *block, unsigned first,
                                                const kdrt__ray_setup *s, kdrt__candidates *c)
{
    const kdrt__x4 zero = kdrt__x4_set1(0.0f), one = kdrt__x4_set1(1.0f);
    kdrt__x4 p0[3], e1[3], e2[3], tv[3], d[3], pv[3], qv[3], det, inv_det, u, v, t;
    kdrt__x4m keep;
    unsigned mask;
    int a;
    for (a = 0; a < 3; ++a) {
        p0[a] = kdrt__x4_load(block->corner[a] + first);
        e1[a] = kdrt__x4_sub(kdrt__x4_load(block->corner[3 + a] + first), p0[a]);
        e2[a] = kdrt__x4_sub(kdrt__x4_load(block->corner[6 + a] + first), p0[a]);
        tv[a] = kdrt__x4_sub(kdrt__x4_set1(s->org[a]), p0[a]);
        d[a] = kdrt__x4_set1(s->dir[a]);
    }
    /* kdrt__cross_float and the scalar test's dot products, in their order */
#define KDRT__CROSS(a, b, c)                                                                      \
    (c[0] = kdrt__x4_sub(kdrt__x4_mul(a[1], b[2]), kdrt__x4_mul(a[2], b[1])),                     \
     c[1] = kdrt__x4_sub(kdrt__x4_mul(a[2], b[0]), kdrt__x4_mul(a[0], b[2])),                     \
     c[2] = kdrt__x4_sub(kdrt__x4_mul(a[0], b[1]), kdrt__x4_mul(a[1], b[0])))
#define KDRT__DOT(a, b)                                                                           \
    kdrt__x4_add(kdrt__x4_add(kdrt__x4_mul(a[0], b[0]), kdrt__x4_mul(a[1], b[1])),                \
                 kdrt__x4_mul(a[2], b[2]))
    KDRT__CROSS(d, e2, pv);
    det = KDRT__DOT(e1, pv);
    inv_det = kdrt__x4_div(one, det);
    u = kdrt__x4_mul(KDRT__DOT(tv, pv), inv_det);
    KDRT__CROSS(tv, e1, qv);
    v = kdrt__x4_mul(KDRT__DOT(d, qv), inv_det);
    t = kdrt__x4_mul(KDRT__DOT(e2, qv), inv_det);
#undef KDRT__CROSS
#undef KDRT__DOT
    keep = kdrt__x4m_and(kdrt__x4_ne(det, zero),
                         kdrt__x4m_and(kdrt__x4_ge(u, zero), kdrt__x4_le(u, one)));
    keep = kdrt__x4m_and(keep, kdrt__x4m_and(kdrt__x4_ge(v, zero),
                                             kdrt__x4_le(kdrt__x4_add(u, v), one)));
    mask = kdrt__x4m_bits(keep);
    if (!mask) return 0;
    kdrt__x4_store(c->t + first, t), kdrt__x4_store(c->u + first, u);
    kdrt__x4_store(c->v + first, v);
    c->front |= kdrt__x4m_bits(kdrt__x4_gt(det, zero)) << first;
    return mask;
}

/* kdrt__intersect_fast on a block's 8 lanes: what kdrt__block_fast_avx2 finds. */
static unsigned kdrt__block_fast_x4(const kdrt__block *block, const kdrt__ray_setup *s,
                                    kdrt__candidates *c)
{
    c->front = 0;
    return kdrt__fast_x4(block, 0, s, c) | kdrt__fast_x4(block, 4, s, c) << 4;
}
#else
static kdrt_kernel kdrt__kernel_x4(void) { return KDRT_KERNEL_SCALAR; }
#endif

/* ==== traversal ==== */

#define KDRT__MAILBOX 32u /* entries; a power of two, as the traversal masks by it */
typedef char kdrt__mailbox_is_a_power_of_two[(KDRT__MAILBOX & (KDRT__MAILBOX - 1u)) == 0 ? 1 : -1];

typedef struct kdrt__todo {
    uint32_t node;
    float t0, t1;
} kdrt__todo;

#ifdef KDRT_TRAVERSAL_STATS
#define KDRT__COUNT(stats, field, n) ((void)((stats) && ((stats)->field += (n))))
#else
#define KDRT__COUNT(stats, field, n) ((void)(stats)) /* compiled out: the hot loop stays as it is */
#endif


/* One inner node of a walk (node, reached over [*t0, *t1]): the child to visit next, with its
   range in *t0, *t1, the other pushed on the stack when the ray may reach it too. */
static KDRT__FORCEINLINE uint32_t kdrt__descend(const kdrt__node *n, uint32_t node,
                                               const kdrt__ray_setup *s, float *t0, float *t1,
                                               kdrt__todo *stack, uint32_t *sp)
{
    uint32_t axis = kdrt__node_axis(n);
    float split = n->u.split, o = s->org[axis];
    float t_split = (split - o) * s->inv_dir[axis];
    int below_first = o < split || (o == split && s->dir[axis] <= 0.0f);
    uint32_t near_child = below_first ? node + 1 : kdrt__node_above(n);
    uint32_t far_child = below_first ? kdrt__node_above(n) : node + 1;
    if (t_split != t_split) {
        /* 0 * infinity: the ray lies in the plane and may hit either side's triangles. */
        KDRT_ASSERT(*sp < KDRT_MAX_DEPTH);
        stack[*sp].node = far_child, stack[*sp].t0 = *t0, stack[*sp].t1 = *t1, ++*sp;
        return near_child;
    }
    if (t_split == 0.0f && *t0 <= 0.0f) {
        /* The origin is on the plane: the ray moves into near_child, but at t = 0 it also
           touches far_child's triangles lying in the plane. */
        KDRT_ASSERT(*sp < KDRT_MAX_DEPTH);
        stack[*sp].node = near_child, stack[*sp].t0 = *t0, stack[*sp].t1 = *t1, ++*sp;
        *t1 = 0.0f;
        return far_child;
    }
    if (t_split <= 0.0f || t_split * (1.0f - KDRT__T_SLACK) > *t1)
        return near_child; /* the plane is behind the origin or beyond the range */
    if (t_split * (1.0f + KDRT__T_SLACK) < *t0) return far_child; /* the range starts past it */
    KDRT_ASSERT(*sp < KDRT_MAX_DEPTH);
    stack[*sp].node = far_child, stack[*sp].t0 = t_split * (1.0f - KDRT__T_SLACK);
    stack[*sp].t1 = *t1, ++*sp;
    *t1 = t_split * (1.0f + KDRT__T_SLACK);
    return near_child;
}

/* The leaf that hint names if the walk may start there: a leaf of this tree whose box holds the
   origin strictly inside (on a face, the ray could touch the neighbour's triangles at t = 0, or
   lie in the plane), else KDRT__NO_ROPE: the walk starts at the root. */
static KDRT__FORCEINLINE uint32_t kdrt__start_cell(const kdrt_tree *tree, uint32_t hint,
                                                  const float org[3])
{
    const kdrt__cell *c;
    if (hint == 0 || hint >= tree->stats.nodes || !kdrt__node_is_leaf(&tree->nodes[hint]))
        return KDRT__NO_ROPE;
    c = &tree->cells[tree->cell_of[hint]];
    if (!(c->lo[0] < org[0] && org[0] < c->hi[0] && c->lo[1] < org[1] && org[1] < c->hi[1] &&
          c->lo[2] < org[2] && org[2] < c->hi[2]))
        return KDRT__NO_ROPE;
    return hint;
}

/* One step of the rope walk from the leaf with cell c, whose triangles have been tested, bound
   being the best hit's t (or the range's end): 0 when the walk is done (the ray leaves the cell
   past bound, or leaves the tree), 1 with the next leaf in *node, -1 when rounding leaves the way
   in doubt (the ray leaves near an edge or a corner of the cell, or passes a plane near where it
   enters the next): the walk goes on from the root, from *restart on. Exit distances carry the
   split planes' rounding bound, KDRT__T_SLACK; every decision is one the bounds prove. */
static KDRT__FORCEINLINE int kdrt__rope_step(const kdrt_tree *tree, const kdrt__cell *c,
                                            const kdrt__ray_setup *s, float bound,
                                            uint32_t *node, float *restart,
                                            kdrt_traversal_stats *stats)
{
    float t_exit = INFINITY, t_next = INFINITY, lo, hi;
    uint32_t next;
    int a, face = 0;
    for (a = 0; a < 3; ++a) {
        float t;
        if (!kdrt__finite(s->inv_dir[a])) continue; /* parallel to the axis' faces */
        t = ((s->dir[a] > 0.0f ? c->hi[a] : c->lo[a]) - s->org[a]) * s->inv_dir[a];
        if (t < t_exit) t_next = t_exit, t_exit = t, face = a;
        else if (t < t_next) t_next = t;
    }
    lo = t_exit * (1.0f - KDRT__T_SLACK), hi = t_exit * (1.0f + KDRT__T_SLACK);
    if (bound < lo) return 0; /* every nearer hit lies in the cell */
    *restart = lo;
    if (t_next * (1.0f - KDRT__T_SLACK) <= hi) return -1; /* which face is in doubt */
    next = c->rope[2 * face + (s->dir[face] > 0.0f)];
    if (next == KDRT__NO_ROPE) return 0; /* out of the tree: nothing more to hit */
    KDRT__COUNT(stats, rope_steps, 1);
    while (!kdrt__node_is_leaf(&tree->nodes[next])) {
        /* Down to the child the ray is in where it enters, t_exit: on the origin's side of the
           plane until it crosses it. */
        const kdrt__node *n = &tree->nodes[next];
        const uint32_t axis = kdrt__node_axis(n);
        const float split = n->u.split, o = s->org[axis];
        const float t_split = (split - o) * s->inv_dir[axis];
        const int below_first = o < split || (o == split && s->dir[axis] <= 0.0f);
        const uint32_t near_child = below_first ? next + 1 : kdrt__node_above(n);
        KDRT__COUNT(stats, rope_nodes, 1);
        if (t_split != t_split) return -1; /* the ray lies in the plane */
        if (t_split <= 0.0f || t_split * (1.0f - KDRT__T_SLACK) > hi) next = near_child;
        else if (t_split * (1.0f + KDRT__T_SLACK) < lo)
            next = below_first ? kdrt__node_above(n) : next + 1;
        else return -1; /* it crosses the plane about where it enters */
    }
    *node = next;
    return 1;
}

/* One leaf of a walk: its blocks tested by the tree's kernel, taking nearer hits into best; 1 when
   any_hit and one was found (the walk is then done). Shared by the rope walk and the walk from
   the root, and inlined into each, so that their constant arguments reach it. */
static KDRT__FORCEINLINE int kdrt__test_leaf(const kdrt_tree *tree, const kdrt__node *n,
                                             const kdrt__ray_setup *s, kdrt_hit *best, int any_hit,
                                             int ruled, uint32_t *tested,
                                             kdrt_traversal_stats *stats)
{
    /* Indexed, not a pointer formed up front: an empty tree has no blocks at all. */
    uint32_t i, first = n->u.first, count = kdrt__node_count(n);
    KDRT__COUNT(stats, leaves, 1);
    KDRT__COUNT(stats, empty_leaves, count == 0);
#if defined(KDRT__AVX2) || defined(KDRT__X4)
    if (tree->simd) {
        for (i = 0; i < count; i += KDRT__LANES) {
            const kdrt__block *block = &tree->blocks[first + i / KDRT__LANES];
            kdrt__candidates candidates;
#if defined(KDRT__AVX2)
            const unsigned mask = tree->watertight ? kdrt__block_watertight_avx2(block, s, &candidates)
                                                   : kdrt__block_fast_avx2(block, s, &candidates);
#else
            const unsigned mask = tree->watertight ? kdrt__block_watertight_x4(block, s, &candidates)
                                                   : kdrt__block_fast_x4(block, s, &candidates);
#endif
            const int found = mask && kdrt__accept_lanes(best, block, mask, &candidates, s, ruled);
            KDRT__COUNT(stats, block_tests, 1);
            KDRT__COUNT(stats, triangle_tests, count - i < KDRT__LANES ? count - i : KDRT__LANES);
            if (found && any_hit) return 1;
        }
        return 0;
    }
#endif
    for (i = 0; i < count; ++i) {
        const kdrt__block *block = &tree->blocks[first + i / KDRT__LANES];
        const uint32_t lane = i % KDRT__LANES, id = block->id[lane];
        uint32_t *box = &tested[id & (KDRT__MAILBOX - 1u)];
        int found;
        if (*box == id) continue;
        *box = id;
        KDRT__COUNT(stats, triangle_tests, 1);
        found = tree->watertight ? kdrt__intersect_watertight(block, lane, s, best, ruled)
                                 : kdrt__intersect_fast(block, lane, s, best, ruled);
        if (found && any_hit) return 1;
    }
    return 0;
}

/* kdrt__traverse's walk of a ray set up in *s over [t0, t1], best a miss with best->t its
   bound; from the start cell hint when it holds the origin. */
static KDRT__FORCEINLINE int kdrt__walk_ray(const kdrt_tree *tree, uint32_t hint,
                                            const kdrt__ray_setup *s, float t0, float t1,
                                            kdrt_hit *best, int any_hit, int ruled,
                                            kdrt_traversal_stats *stats)
{
    kdrt__todo stack[KDRT_MAX_DEPTH];
    uint32_t sp = 0, node;
    /* Mailbox (scalar kernel): the triangles tested last, by their low bits. A triangle split
       across leaves is tested once per ray: a second test could only repeat the first answer. */
    uint32_t tested[KDRT__MAILBOX];
    uint32_t hit_cell = 0; /* the leaf that holds the best hit so far (kdrt_hit.cell) */
    memset(tested, 0xFF, sizeof tested);

    node = kdrt__start_cell(tree, hint, s->org);
    if (node != KDRT__NO_ROPE) {
        /* The rope walk: from the start cell leaf to leaf, until the best hit lies in the cell
           or the ray leaves the tree. A ray cannot pass more cells than there are: more steps are
           a tree whose odd splits (the median builder's may lie outside a node's box) it does not
           trust. Where a step is in doubt, the cells behind have been tested up to restart: from
           there, the walk from the root takes over what is left of the range. */
        uint32_t steps = 0, next;
        float restart = t0;
        int step;
        for (;;) {
            if (kdrt__test_leaf(tree, &tree->nodes[node], s, best, any_hit, ruled, tested, stats))
                return 1;
            step = kdrt__rope_step(tree, &tree->cells[tree->cell_of[node]], s, best->t, &next,
                                   &restart, stats);
            if (step == 0) {
                hit_cell = node;
                goto done;
            }
            if (step < 0 || ++steps > tree->stats.leaves) break;
            node = next;
        }
        KDRT__COUNT(stats, restarts, 1);
        if (restart > t0) t0 = restart;
        if (t0 > best->t) goto done;
    }

    /* The walk from the root, with a stack. */
    node = 0;
    for (;;) {
        const kdrt__node *n = &tree->nodes[node];
        if (!kdrt__node_is_leaf(n)) {
            KDRT__COUNT(stats, inner_nodes, 1);
            node = kdrt__descend(n, node, s, &t0, &t1, stack, &sp);
            continue;
        }
        if (kdrt__test_leaf(tree, n, s, best, any_hit, ruled, tested, stats)) return 1;
        if (!any_hit && best->t <= t1) hit_cell = node; /* the best hit so far may lie here */
        /* Next node that starts no later than the best hit: any triangle in a node starting
           beyond it is farther away. */
        do {
            if (sp == 0) goto done;
            --sp;
            node = stack[sp].node, t0 = stack[sp].t0, t1 = stack[sp].t1;
        } while (t0 > best->t);
    }
done:
    if (best->triangle == KDRT_INVALID_ID) return 0;
    best->cell = hit_cell;
    return 1;
}

/* The one traversal, front to back, for the nearest hit or (any_hit) the first found; stats, when
   counting is compiled in and it is not NULL, gets the work done. Inlined into each query, so
   that a plain one (no rules, no list: ruled a constant 0) is the walk without rules. */
static KDRT__FORCEINLINE int kdrt__traverse(const kdrt_tree *tree, const kdrt_ray *ray,
                                            const kdrt__rules *rules, kdrt_hit *best, int any_hit,
                                            kdrt__hit_list *list, kdrt_traversal_stats *stats)
{
    kdrt__ray_setup s;
    float t0, t1;
    /* Whether rules or a list apply (a list comes with rules, which name its hits): from the
       arguments, not from s, so that it is a constant where they are. */
    const int ruled = rules != NULL;

    KDRT_ASSERT(!list || rules);
    kdrt__miss(best);
    if (!kdrt__setup_ray(ray, &s) || !kdrt__clip_to_box(&tree->bounds, &s, &t0, &t1)) return 0;
    best->t = s.tmax;
    s.list = list; /* best is then the bound: the list's last hit once it is full */
    s.rules = rules;
    best->t = kdrt__list_bound(list, best->t); /* full from an earlier walk (scenes) */
    return kdrt__walk_ray(tree, ray->cell, &s, t0, t1, best, any_hit, ruled, stats);
}


/* The rules for a walk of tree under query (NULL: none) in *storage, or NULL when the walk needs
   none (no flag, no filter, no mask to test, no list: force) and can run plain. instance: the
   instance being walked (KDRT_INVALID_ID: none), mirrored when its transform is. The caller has
   turned away a query mask of 0, which sees nothing. */
static const kdrt__rules *kdrt__rules_for(const kdrt_query *query, const kdrt_ray *ray,
                                          const kdrt_tree *tree, uint32_t instance, int mirrored,
                                          int force, kdrt__rules *storage)
{
    uint32_t flags = query ? query->flags : 0u;
    const int test_mask = !tree->masks_full; /* NULL is kdrt_default_query(): every bit */
    if (!flags && !(query && query->filter) && !test_mask && !force) return NULL;
    if (mirrored) /* the world sees the other face */
        flags = (flags & KDRT_QUERY_CULL_BACK_FACES ? (uint32_t)KDRT_QUERY_CULL_FRONT_FACES : 0u) |
                (flags & KDRT_QUERY_CULL_FRONT_FACES ? (uint32_t)KDRT_QUERY_CULL_BACK_FACES : 0u);
    storage->flags = flags;
    storage->mask = query ? query->mask : 0xFFFFFFFFu;
    storage->test_mask = test_mask;
    storage->filter = query ? query->filter : NULL;
    storage->user = query ? query->user : NULL;
    storage->ray = ray;
    storage->meshes = &tree->meshes;
    storage->instance = instance;
    return storage;
}

/* The nearest hit, for kdrt_intersect and its _counted form; inlined as the walk is, so that
   each keeps its constant arguments. */
static KDRT__FORCEINLINE int kdrt__intersect(const kdrt_tree *tree, const kdrt_ray *ray,
                                             kdrt_hit *hit, kdrt_traversal_stats *stats)
{
    if (!hit) return 0;
    if (!tree || !ray) {
        kdrt__miss(hit);
        return 0;
    }
    return kdrt__traverse(tree, ray, NULL, hit, 0, NULL, stats);
}

KDRT_API int kdrt_intersect(const kdrt_tree *tree, const kdrt_ray *ray, kdrt_hit *hit)
{
    return kdrt__intersect(tree, ray, hit, NULL);
}

#ifdef KDRT_TRAVERSAL_STATS
KDRT_API int kdrt_intersect_counted(const kdrt_tree *tree, const kdrt_ray *ray, kdrt_hit *hit,
                                    kdrt_traversal_stats *stats)
{
    return kdrt__intersect(tree, ray, hit, stats);
}
#endif

KDRT_API int kdrt_occluded(const kdrt_tree *tree, const kdrt_ray *ray)
{
    kdrt_hit hit;
    return tree && ray && kdrt__traverse(tree, ray, NULL, &hit, 1, NULL, NULL);
}

KDRT_API kdrt_query kdrt_default_query(void)
{
    kdrt_query q;
    memset(&q, 0, sizeof q);
    q.mask = 0xFFFFFFFFu;
    return q;
}

/* A walk of one tree with or without rules (any_hit: *best is not filled in). Without, it is
   kdrt_intersect() or kdrt_occluded() itself, their constant arguments folded in. Used by the
   _query forms and by scenes, for each tree they walk. */
static int kdrt__walk(const kdrt_tree *tree, const kdrt_ray *ray, const kdrt__rules *rules,
                      kdrt_hit *best, int any_hit, kdrt__hit_list *list)
{
    if (rules) return kdrt__traverse(tree, ray, rules, best, any_hit, list, NULL);
    return any_hit ? kdrt_occluded(tree, ray) : kdrt_intersect(tree, ray, best);
}

KDRT_API int kdrt_intersect_query(const kdrt_tree *tree, const kdrt_ray *ray,
                                  const kdrt_query *query, kdrt_hit *hit)
{
    kdrt__rules storage;
    if (!hit) return 0;
    kdrt__miss(hit);
    if (!tree || !ray || (query && query->mask == 0)) return 0;
    return kdrt__walk(tree, ray, kdrt__rules_for(query, ray, tree, KDRT_INVALID_ID, 0, 0, &storage),
                      hit, 0, NULL);
}

KDRT_API int kdrt_occluded_query(const kdrt_tree *tree, const kdrt_ray *ray,
                                 const kdrt_query *query)
{
    kdrt__rules storage;
    kdrt_hit hit;
    if (!tree || !ray || (query && query->mask == 0)) return 0;
    return kdrt__walk(tree, ray, kdrt__rules_for(query, ray, tree, KDRT_INVALID_ID, 0, 0, &storage),
                      &hit, 1, NULL);
}

KDRT_API uint32_t kdrt_intersect_k(const kdrt_tree *tree, const kdrt_ray *ray,
                                   const kdrt_query *query, kdrt_hit *hits, uint32_t capacity)
{
    kdrt__hit_list list;
    kdrt__rules storage;
    kdrt_hit bound;
    if (!tree || !ray || !hits || capacity == 0 || (query && query->mask == 0)) return 0;
    list.hits = hits, list.count = 0, list.capacity = capacity;
    kdrt__traverse(tree, ray, kdrt__rules_for(query, ray, tree, KDRT_INVALID_ID, 0, 1, &storage),
                   &bound, 0, &list, NULL);
    return list.count;
}

/* ==== batches: packets of rays that walk the tree together ==== */

/* kdrt_intersect() into hit, or kdrt_occluded() where hit is NULL, counting into stats. Out of
   line, and compiled for the caller's target, not AVX2's: the walk's speed is the single-ray
   query's. */
KDRT__NOINLINE static int kdrt__trace_alone(const kdrt_tree *tree, const kdrt_ray *ray,
                                            kdrt_hit *hit, kdrt_traversal_stats *stats)
{
    kdrt_hit scratch;
    return hit ? kdrt__intersect(tree, ray, hit, stats)
               : kdrt__traverse(tree, ray, NULL, &scratch, 1, NULL, stats);
}

/* rays[0 .. count) one by one: into hits, or occluded where hits is NULL. Returns how many hit. */
static uint32_t kdrt__batch_alone(const kdrt_tree *tree, const kdrt_ray *rays, uint32_t count,
                                  kdrt_hit *hits, uint8_t *occluded, kdrt_traversal_stats *stats)
{
    uint32_t i, found = 0;
    for (i = 0; i < count; ++i) {
        const int hit = kdrt__trace_alone(tree, &rays[i], hits ? &hits[i] : NULL, stats);
        if (!hits) occluded[i] = (uint8_t)hit;
        found += (uint32_t)hit;
    }
    return found;
}

#ifdef KDRT__AVX2
static int kdrt__bit_count(unsigned bits)
{
    int n = 0;
    for (; bits; bits &= bits - 1u) ++n;
    return n;
}

/* The single-ray walk of a batch's ray, set up already (kdrt__walk_ray). Out of line: the batch
   loop stays small. */
KDRT__NOINLINE static int kdrt__walk_alone(const kdrt_tree *tree, uint32_t hint,
                                           const kdrt__ray_setup *s, float t0, float t1,
                                           kdrt_hit *best, int any_hit, kdrt_traversal_stats *stats)
{
    return any_hit ? kdrt__walk_ray(tree, hint, s, t0, t1, best, 1, 0, stats)
                   : kdrt__walk_ray(tree, hint, s, t0, t1, best, 0, 0, stats);
}

/* The block test and the leaf test of the single-ray walk, out of line for the packets: inlined
   into the AVX-512 code, their multiplies and adds could be fused into FMAs (AVX-512 implies
   FMA), and their answers would no longer be the single-ray walk's. */
KDRT__NOINLINE KDRT__TARGET_AVX2 static unsigned kdrt__block_test_apart(const kdrt__block *block,
                                                                       const kdrt__ray_setup *s,
                                                                       kdrt__candidates *c)
{
    return kdrt__block_watertight_avx2(block, s, c);
}

KDRT__NOINLINE static int kdrt__test_leaf_apart(const kdrt_tree *tree, const kdrt__node *n,
                                                const kdrt__ray_setup *s, kdrt_hit *best,
                                                int any_hit, kdrt_traversal_stats *stats)
{
    return kdrt__test_leaf(tree, n, s, best, any_hit, 0, NULL, stats);
}

/* A packet (AVX2 and AVX-512 kernels): up to 8 or 16 consecutive rays of a batch whose
   directions have no zero or tiny component and share their signs and their largest axis, so
   that at every split plane
   they take its sides in the same order and the watertight test shears them alike. Each lane
   keeps its own setup, range and best hit, and takes at every node the decision kdrt__descend
   takes for it alone, so each visits the leaves its own walk from the root visits, in the same
   order, and gets the same answer bit for bit; the packet only shares the way. */
typedef struct kdrt__packet {
    kdrt__ray_setup s[KDRT__PACKET_MAX];
    float org[3][KDRT__PACKET_MAX], inv_dir[3][KDRT__PACKET_MAX]; /* the lanes' s, axis by axis */
    float shear[3][KDRT__PACKET_MAX]; /* the lanes' shear_x, _y, _z */
    float bound[KDRT__PACKET_MAX];    /* the best hit's t so far, or the range's end */
    kdrt_hit *best[KDRT__PACKET_MAX];
    uint32_t hit_cell[KDRT__PACKET_MAX]; /* as kdrt__walk_ray's hit_cell */
    /* Watertight tree: the leaves are tested triangle by triangle against the packet
       (kdrt__packet_leaf), within the bounds over the lanes of their origins' kx, ky, kz
       (lo[0..3), hi[0..3)) and of their shear_x, shear_y (lo[3..5), hi[3..5)). */
    int sheared, kx, ky, kz;
    float lo[5], hi[5];
    int point;         /* lo[0..3) = hi[0..3): the lanes share their origin (a camera's rays) */
    unsigned negative; /* bit a: the directions' component a is negative */
    unsigned lanes;    /* lanes still walking */
    unsigned alone;    /* lanes handed back to the single-ray walk (kdrt__packet_walk) */
    unsigned found;    /* any_hit: lanes that found one */
} kdrt__packet;

/* One axis of one corner of kdrt__packet_culled_avx2: folds into *above and *below the lanes
   whose corner lies surely on that side of every ray. point: the lanes share their origin
   (d_lo = d_hi, dz_lo = dz_hi), which saves half the products. */
KDRT__TARGET_AVX2 static KDRT__FORCEINLINE void kdrt__cull_axis_avx2(
    __m256 d_lo, __m256 d_hi, __m256 dz_lo, __m256 dz_hi, __m256 s_lo, __m256 s_hi, int point,
    __m256 *above, __m256 *below)
{
    const __m256 sign = _mm256_set1_ps(-0.0f), margin = _mm256_set1_ps(9.5367431640625e-7f);
    __m256 w_lo, w_hi, size;
    if (point) {
        const __m256 w0 = _mm256_mul_ps(s_lo, dz_lo), w1 = _mm256_mul_ps(s_hi, dz_lo);
        w_lo = _mm256_min_ps(w0, w1), w_hi = _mm256_max_ps(w0, w1);
        size = _mm256_andnot_ps(sign, d_lo);
    } else {
        const __m256 w0 = _mm256_mul_ps(s_lo, dz_lo), w1 = _mm256_mul_ps(s_lo, dz_hi);
        const __m256 w2 = _mm256_mul_ps(s_hi, dz_lo), w3 = _mm256_mul_ps(s_hi, dz_hi);
        w_lo = _mm256_min_ps(_mm256_min_ps(w0, w1), _mm256_min_ps(w2, w3));
        w_hi = _mm256_max_ps(_mm256_max_ps(w0, w1), _mm256_max_ps(w2, w3));
        size = _mm256_max_ps(_mm256_andnot_ps(sign, d_lo), _mm256_andnot_ps(sign, d_hi));
    }
    {
        const __m256 x_lo = _mm256_sub_ps(d_lo, w_hi), x_hi = _mm256_sub_ps(d_hi, w_lo);
        const __m256 m = _mm256_mul_ps(
            _mm256_add_ps(size, _mm256_max_ps(_mm256_andnot_ps(sign, w_lo), _mm256_andnot_ps(sign, w_hi))),
            margin);
        *above = _mm256_and_ps(*above, _mm256_cmp_ps(x_lo, m, _CMP_GT_OQ));
        *below = _mm256_and_ps(*below, _mm256_cmp_ps(x_hi, _mm256_xor_ps(m, sign), _CMP_LT_OQ));
    }
}

/* The triangles of a block that surely miss every ray of the packet: seen from each ray (its
   origin moved to 0 and sheared along +z, as the watertight test sees it), all three corners lie
   on one side of x = 0 or of y = 0. Rounding is monotone, so the test's own sheared corners of
   every lane lie within the bounds computed here from the bounds of the lanes' origins and
   shears (products at the box's corners); the margin, 2^-20 of the magnitudes, covers a compiler
   that fuses the test's multiply and subtract. A triangle with its corners on one side of the ray
   has edge functions of both signs: the test would reject it for each ray. */
KDRT__TARGET_AVX2 static KDRT__FORCEINLINE unsigned kdrt__packet_culled_avx2(const kdrt__block *block,
                                                                            const kdrt__packet *p,
                                                                            int point)
{
    const __m256 oz_lo = _mm256_set1_ps(p->lo[2]), oz_hi = _mm256_set1_ps(p->hi[2]);
    const __m256 ox_lo = _mm256_set1_ps(p->lo[0]), ox_hi = _mm256_set1_ps(p->hi[0]);
    const __m256 oy_lo = _mm256_set1_ps(p->lo[1]), oy_hi = _mm256_set1_ps(p->hi[1]);
    const __m256 sx_lo = _mm256_set1_ps(p->lo[3]), sx_hi = _mm256_set1_ps(p->hi[3]);
    const __m256 sy_lo = _mm256_set1_ps(p->lo[4]), sy_hi = _mm256_set1_ps(p->hi[4]);
    const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    __m256 above_x = all, below_x = all, above_y = all, below_y = all;
#define KDRT__CULL_CORNER(k)                                                                   \
    do {                                                                                       \
        const __m256 pz = _mm256_load_ps(block->corner[3 * (k) + p->kz]);                      \
        const __m256 px = _mm256_load_ps(block->corner[3 * (k) + p->kx]);                      \
        const __m256 py = _mm256_load_ps(block->corner[3 * (k) + p->ky]);                      \
        const __m256 dz_lo = _mm256_sub_ps(pz, oz_hi), dz_hi = _mm256_sub_ps(pz, oz_lo);       \
        kdrt__cull_axis_avx2(_mm256_sub_ps(px, ox_hi), _mm256_sub_ps(px, ox_lo), dz_lo, dz_hi, \
                             sx_lo, sx_hi, point, &above_x, &below_x);                         \
        kdrt__cull_axis_avx2(_mm256_sub_ps(py, oy_hi), _mm256_sub_ps(py, oy_lo), dz_lo, dz_hi, \
                             sy_lo, sy_hi, point, &above_y, &below_y);                         \
    } while (0)
    KDRT__CULL_CORNER(0);
    KDRT__CULL_CORNER(1);
    KDRT__CULL_CORNER(2);
#undef KDRT__CULL_CORNER
    return (unsigned)_mm256_movemask_ps(
        _mm256_or_ps(_mm256_or_ps(above_x, below_x), _mm256_or_ps(above_y, below_y)));
}

typedef char kdrt__ray_is_9_floats[sizeof(kdrt_ray) == 9 * sizeof(float) ? 1 : -1];

/* 1 where lanes of bits agree with the lane first: the movemask bits of one test. */
static unsigned kdrt__same_bit(unsigned bits, unsigned first)
{
    return (bits >> first) & 1u ? bits : ~bits;
}

/* Fewer rays than this in a packet go one by one: they share few steps, and a packet of two
   walked at 1.4 lanes a step on shuffled rays, slower than alone (kdrt-ray-costs). */
#define KDRT__PACKET_MIN_LANES 4
/* A packet whose origins span more than this fraction of the tree's box on an axis, or whose
   shears span more than this, goes one by one: its rays part ways soon. */
#define KDRT__PACKET_SPREAD 0.0625f

/* How many of rays[0 .. n) have the first one's direction signs: sign bits, in scalar code, so
   that incoherent rays run no vector code at all. (After AVX-512 code, Intel cores run slower
   for a while: the single-ray walks of shuffled rays were 5% slower with a packet tried every
   65 groups.) */
static uint32_t kdrt__same_signs(const kdrt_ray *rays, uint32_t n)
{
    uint32_t i, same = 0, first = 0;
    for (i = 0; i < n; ++i) {
        uint32_t bits[3];
        memcpy(bits, rays[i].dir, sizeof bits);
        bits[0] = (bits[0] >> 31) | (bits[1] >> 31) << 1 | (bits[2] >> 31) << 2;
        if (i == 0) first = bits[0];
        same += bits[0] == first;
    }
    return same;
}

/* After a group that formed no packet: the groups to skip before trying again, twice as many
   each time from the second failure on (up to 64). */
static uint32_t kdrt__failed_packet(uint32_t *failures)
{
    ++*failures;
    return *failures < 2 ? 0u : *failures < 8 ? 1u << (*failures - 2) : 64u;
}

/* Whether p's lanes walk together: enough of them, their origins and shears close. */
static int kdrt__packet_together(const kdrt_tree *tree, const kdrt__packet *p)
{
    const int axis[3] = {p->kx, p->ky, p->kz};
    int b, together = kdrt__bit_count(p->lanes) >= KDRT__PACKET_MIN_LANES;
    if (!together) return 0; /* and the bounds are set where the setup found lanes */
    for (b = 0; b < 3; ++b)
        together &= p->hi[b] - p->lo[b] <=
                    KDRT__PACKET_SPREAD * (tree->bounds.max[axis[b]] - tree->bounds.min[axis[b]]);
    return together && p->hi[3] - p->lo[3] <= KDRT__PACKET_SPREAD &&
           p->hi[4] - p->lo[4] <= KDRT__PACKET_SPREAD;
}

/* kdrt__batch_avx2 and kdrt__batch_avx512, and their packet walks (PACKETS). */
#define KDRT__PACKET_WIDTH 8
#define KDRT__PACKET_PARTS 2
#include KDRT_HEADER_FILENAME
#undef KDRT__PACKET_WIDTH
#undef KDRT__PACKET_PARTS
/* GCC 12's AVX-512 intrinsics are macros at -O0 whose mask arguments (0xFFFF) convert to signed
   types, which -Woverflow and -Wsign-conversion name, in the user's build: not kdrt's to fix. */
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverflow"
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#endif
#define KDRT__PACKET_WIDTH 16
#define KDRT__PACKET_PARTS 3
#include KDRT_HEADER_FILENAME
#undef KDRT__PACKET_WIDTH
#undef KDRT__PACKET_PARTS
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
#endif

/* Whether query lets every hit of tree count, so that the plain walk answers it. */
static int kdrt__query_is_plain(const kdrt_tree *tree, const kdrt_query *query)
{
    return tree->masks_full && (!query || (!query->flags && !query->filter && query->mask));
}

/* rays[0 .. count) on tree under a plain query: into hits (nearest hit) or occluded (any_hit).
   The scalar kernel walks them one by one. Returns how many hit. */
static uint32_t kdrt__batch(const kdrt_tree *tree, const kdrt_ray *rays, uint32_t count,
                            kdrt_hit *hits, uint8_t *occluded, int any_hit,
                            kdrt_traversal_stats *stats)
{
#ifdef KDRT__AVX2
    if (tree->simd == KDRT_KERNEL_AVX512)
        return kdrt__batch_avx512(tree, rays, count, hits, occluded, any_hit, stats);
    if (tree->simd == KDRT_KERNEL_AVX2)
        return kdrt__batch_avx2(tree, rays, count, hits, occluded, any_hit, stats);
#endif
    return kdrt__batch_alone(tree, rays, count, any_hit ? NULL : hits, occluded, stats);
}

KDRT_API uint32_t kdrt_intersect_batch(const kdrt_tree *tree, const kdrt_ray *rays,
                                       uint32_t count, const kdrt_query *query, kdrt_hit *hits)
{
    uint32_t i, found = 0;
    if (!hits) return 0;
    if (tree && rays && kdrt__query_is_plain(tree, query))
        return kdrt__batch(tree, rays, count, hits, NULL, 0, NULL);
    for (i = 0; i < count; ++i) {
        if (tree && rays) found += (uint32_t)kdrt_intersect_query(tree, &rays[i], query, &hits[i]);
        else kdrt__miss(&hits[i]);
    }
    return found;
}

KDRT_API uint32_t kdrt_occluded_batch(const kdrt_tree *tree, const kdrt_ray *rays,
                                      uint32_t count, const kdrt_query *query, uint8_t *occluded)
{
    uint32_t i, found = 0;
    if (!occluded) return 0;
    if (tree && rays && kdrt__query_is_plain(tree, query))
        return kdrt__batch(tree, rays, count, NULL, occluded, 1, NULL);
    for (i = 0; i < count; ++i) {
        occluded[i] = (uint8_t)(tree && rays && kdrt_occluded_query(tree, &rays[i], query));
        found += occluded[i];
    }
    return found;
}

#ifdef KDRT_TRAVERSAL_STATS
KDRT_API uint32_t kdrt_intersect_batch_counted(const kdrt_tree *tree, const kdrt_ray *rays,
                                               uint32_t count, kdrt_hit *hits,
                                               kdrt_traversal_stats *stats)
{
    uint32_t i;
    if (!hits) return 0;
    if (tree && rays) return kdrt__batch(tree, rays, count, hits, NULL, 0, stats);
    for (i = 0; i < count; ++i) kdrt__miss(&hits[i]);
    return 0;
}

KDRT_API uint32_t kdrt_occluded_batch_counted(const kdrt_tree *tree, const kdrt_ray *rays,
                                              uint32_t count, uint8_t *occluded,
                                              kdrt_traversal_stats *stats)
{
    if (!occluded) return 0;
    if (tree && rays) return kdrt__batch(tree, rays, count, NULL, occluded, 1, stats);
    if (count) memset(occluded, 0, count);
    return 0;
}
#endif

/* ==== secondary rays ==== */

/* An instance as the queries use it: the transform and its inverse in double, and the world
   box its tree occupies. */
typedef struct kdrt__instance {
    const kdrt_tree *tree;
    double to_world[12];  /* [R | t], as kdrt_geometry.transform */
    double to_object[9];  /* R^-1: object = R^-1 (world - t) */
    kdrt_aabb box;        /* the tree's box carried into the world and widened; empty: no tree */
    uint32_t id, mask;
    int mirrored;         /* det R < 0: the world sees each triangle's other face */
} kdrt__instance;

/* The point at barycentrics (u, v) of the triangle with corners c, each first carried into the
   world by the instance in unless it is NULL, and its unit geometric normal, the direction of
   (p1 - p0) x (p2 - p0) of the corners as placed, so that a mirror turns it with the winding.
   Either output may be NULL. (Instances are the scenes' (SCENES); they are defined here for
   this.) */
static void kdrt__surface(float c[3][3], const kdrt__instance *in, float u, float v, float point[3],
                          float normal[3])
{
    const double *to_world = in ? in->to_world : NULL;
    double p[3][3], e1[3], e2[3], n[3], length;
    int a, k;
    for (k = 0; k < 3; ++k)
        for (a = 0; a < 3; ++a)
            p[k][a] = to_world ? to_world[4 * a] * c[k][0] + to_world[4 * a + 1] * c[k][1] +
                                     to_world[4 * a + 2] * c[k][2] + to_world[4 * a + 3]
                               : c[k][a];
    for (a = 0; a < 3; ++a) {
        double x, lo = p[0][a], hi = p[0][a];
        e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a];
        /* p0 + u e1 + v e2 in double: exact enough that the float result is within an ulp. Kept
           within the corners: rounded barycentrics (u + v a hair over 1) must not take it out
           of the triangle's box, nor past the largest float when a corner lies there. */
        x = p[0][a] + u * e1[a] + v * e2[a];
        for (k = 1; k < 3; ++k)
            lo = p[k][a] < lo ? p[k][a] : lo, hi = p[k][a] > hi ? p[k][a] : hi;
        if (point) point[a] = (float)(x < lo ? lo : (x > hi ? hi : x));
    }
    if (in) {
        /* The tree's normal carried by the inverse transpose, turned where the transform mirrors
           ((R a) x (R b) = det R R^-T (a x b)): the world corners' own cross product would lose
           the triangle's shape to rounding far from the origin (a unit cube placed at 2e30). */
        double m[3];
        for (a = 0; a < 3; ++a) e1[a] = (double)c[1][a] - c[0][a], e2[a] = (double)c[2][a] - c[0][a];
        kdrt__cross(e1, e2, m);
        for (a = 0; a < 3; ++a)
            n[a] = (in->mirrored ? -1.0 : 1.0) * (in->to_object[a] * m[0] + in->to_object[3 + a] * m[1] +
                                                  in->to_object[6 + a] * m[2]);
    } else {
        kdrt__cross(e1, e2, n);
    }
    length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (normal)
        for (a = 0; a < 3; ++a) normal[a] = length > 0.0 ? (float)(n[a] / length) : 0.0f;
}

/* The corners of triangle tri of mesh m, for a hit the caller hands back: 0 when the mesh has
   no such triangle or the build could not have used it (a hand-made hit). */
static int kdrt__hit_corners(const kdrt_triangles *m, uint32_t tri, float p[3][3])
{
    return tri < m->triangle_count && kdrt__check_triangle(m, tri, p) == KDRT_SUCCESS;
}

KDRT_API int kdrt_hit_surface(const kdrt_tree *tree, const kdrt_hit *hit, float point[3],
                              float normal[3])
{
    float p[3][3];
    /* From the caller's buffers, which the tree borrows anyway: hit->triangle is the caller's
       index, and the tree's copy is in leaf order, so finding a triangle there would take an
       inverse map (4 more bytes a triangle) for a query made once per hit, not once per test. */
    if (!tree || !hit || !kdrt__hit_corners(&tree->meshes.parts[0].mesh, hit->triangle, p))
        return 0;
    kdrt__surface(p, NULL, hit->u, hit->v, point, normal);
    return 1;
}

KDRT_API void kdrt_offset_ray_origin(const float point[3], const float normal[3],
                                     const float dir[3], float out[3])
{
    /* Waechter & Binder's constants: below 1/32 a fixed 2^-16 step, above it 256 ulps. */
    const float origin = 1.0f / 32.0f, float_scale = 1.0f / 65536.0f, int_scale = 256.0f;
    float n[3], largest = 0.0f;
    int a;
    for (a = 0; a < 3; ++a) {
        if (!kdrt__finite(normal[a])) largest = -1.0f; /* poisoned: leave the point alone */
        if (largest >= 0.0f && kdrt__abs(normal[a]) > largest) largest = kdrt__abs(normal[a]);
    }
    /* Scale so the largest component is 1 (no sqrt needed), and face the side dir leaves on. */
    if (!(largest > 0.0f)) {
        for (a = 0; a < 3; ++a) out[a] = point[a];
        return;
    }
    if (normal[0] * dir[0] + normal[1] * dir[1] + normal[2] * dir[2] < 0.0f) largest = -largest;
    for (a = 0; a < 3; ++a) n[a] = normal[a] / largest;
    for (a = 0; a < 3; ++a) {
        int32_t step = (int32_t)(int_scale * n[a]);
        uint32_t bits;
        float moved;
        if (kdrt__abs(point[a]) < origin) {
            out[a] = point[a] + float_scale * n[a];
            continue;
        }
        /* Adding k to the bits of a float moves it k ulps away from 0 (towards 0 for negative k).
           Unsigned, so the arithmetic wraps instead of overflowing. */
        memcpy(&bits, &point[a], sizeof bits);
        bits += (uint32_t)(point[a] < 0.0f ? -step : step);
        memcpy(&moved, &bits, sizeof moved);
        out[a] = kdrt__finite(moved) ? moved : point[a]; /* next to FLT_MAX: nowhere to go */
    }
}

/* A ray leaving point (on a surface with this normal) in direction dir, for kdrt_spawn_ray and
   kdrt_scene_spawn_ray. */
static void kdrt__leave_surface(const float point[3], const float normal[3], const float dir[3],
                                kdrt_ray *out)
{
    int a;
    kdrt_offset_ray_origin(point, normal, dir, out->org);
    for (a = 0; a < 3; ++a) out->dir[a] = dir[a];
    out->tmin = 0.0f;
    out->tmax = INFINITY;
}

KDRT_API uint32_t kdrt_locate(const kdrt_tree *tree, const float point[3])
{
    uint32_t node = 0;
    int a;
    if (!tree || !point || tree->stats.nodes == 0) return 0;
    for (a = 0; a < 3; ++a) /* NaN fails these too */
        if (!(point[a] >= tree->bounds.min[a] && point[a] <= tree->bounds.max[a])) return 0;
    while (!kdrt__node_is_leaf(&tree->nodes[node])) {
        const kdrt__node *n = &tree->nodes[node];
        node = point[kdrt__node_axis(n)] <= n->u.split ? node + 1 : kdrt__node_above(n);
    }
    return node;
}

/* The start cell of a ray leaving a surface at org: the hit's own cell when it holds org, as it
   does unless the offset crossed a face, else the cell found from the root. */
static uint32_t kdrt__spawn_cell(const kdrt_tree *tree, uint32_t hint, const float org[3])
{
    if (!tree) return 0;
    return kdrt__start_cell(tree, hint, org) != KDRT__NO_ROPE ? hint : kdrt_locate(tree, org);
}

KDRT_API int kdrt_spawn_ray(const kdrt_tree *tree, const kdrt_hit *hit, const float dir[3],
                            kdrt_ray *out)
{
    float point[3], normal[3];
    if (!out) return 0;
    memset(out, 0, sizeof *out);
    if (!dir || !kdrt_hit_surface(tree, hit, point, normal)) return 0; /* zero dir: misses */
    kdrt__leave_surface(point, normal, dir, out);
    out->cell = kdrt__spawn_cell(tree, hit->cell, out->org);
    return 1;
}

/* ==== saved trees: the file format (SAVED TREES) ==== */

/* Little-endian on disk whatever the host: every section is 32-bit words (floats and uint32),
   written as they lie in memory on a little-endian host and swapped word by word elsewhere. */
static int kdrt__little_endian(void)
{
    const uint32_t one = 1u;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 1u;
}

static uint32_t kdrt__swap32(uint32_t x)
{
    return (x >> 24) | ((x >> 8) & 0xFF00u) | ((x << 8) & 0xFF0000u) | (x << 24);
}

static uint32_t kdrt__get32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t kdrt__get64(const unsigned char *p)
{
    return (uint64_t)kdrt__get32(p) | (uint64_t)kdrt__get32(p + 4) << 32;
}

static void kdrt__put32(unsigned char *p, uint32_t x)
{
    p[0] = (unsigned char)x, p[1] = (unsigned char)(x >> 8);
    p[2] = (unsigned char)(x >> 16), p[3] = (unsigned char)(x >> 24);
}

static void kdrt__put64(unsigned char *p, uint64_t x)
{
    kdrt__put32(p, (uint32_t)x);
    kdrt__put32(p + 4, (uint32_t)(x >> 32));
}

static uint32_t kdrt__float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static float kdrt__bits_float(uint32_t u)
{
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* XXH64 (Yann Collet's xxHash, 64-bit, seed 0), streamed: the mesh fingerprint and the header's
   checksum. Word-wise, four independent lanes: several GB/s, and any xxHash library computes
   the same value from the same bytes. */
#define KDRT__P1 0x9E3779B185EBCA87u
#define KDRT__P2 0xC2B2AE3D27D4EB4Fu
#define KDRT__P3 0x165667B19E3779F9u
#define KDRT__P4 0x85EBCA77C2B2AE63u
#define KDRT__P5 0x27D4EB2F165667C5u

typedef struct kdrt__hash {
    uint64_t v[4], length;
    unsigned char tail[32];
    uint32_t tail_size;
} kdrt__hash;

static uint64_t kdrt__rotl64(uint64_t x, unsigned r) { return (x << r) | (x >> (64u - r)); }

/* Eight bytes as a little-endian number; one load where the host is little-endian. */
static uint64_t kdrt__le64(const unsigned char *p, int little)
{
    uint64_t x;
    if (!little) return kdrt__get64(p);
    memcpy(&x, p, sizeof x);
    return x;
}

static uint64_t kdrt__xxh_round(uint64_t acc, uint64_t input)
{
    acc += input * (uint64_t)KDRT__P2;
    return kdrt__rotl64(acc, 31) * (uint64_t)KDRT__P1;
}

static void kdrt__hash_init(kdrt__hash *h)
{
    memset(h, 0, sizeof *h);
    h->v[0] = (uint64_t)KDRT__P1 + (uint64_t)KDRT__P2;
    h->v[1] = (uint64_t)KDRT__P2;
    h->v[2] = 0;
    h->v[3] = (uint64_t)0 - (uint64_t)KDRT__P1;
}

/* Whole 32-byte stripes from p, n of them. */
static void kdrt__hash_stripes(kdrt__hash *h, const unsigned char *p, size_t n, int little)
{
    uint64_t v0 = h->v[0], v1 = h->v[1], v2 = h->v[2], v3 = h->v[3];
    for (; n > 0; --n, p += 32) {
        v0 = kdrt__xxh_round(v0, kdrt__le64(p, little));
        v1 = kdrt__xxh_round(v1, kdrt__le64(p + 8, little));
        v2 = kdrt__xxh_round(v2, kdrt__le64(p + 16, little));
        v3 = kdrt__xxh_round(v3, kdrt__le64(p + 24, little));
    }
    h->v[0] = v0, h->v[1] = v1, h->v[2] = v2, h->v[3] = v3;
}

static void kdrt__hash_bytes(kdrt__hash *h, const void *data, size_t size)
{
    const unsigned char *p = (const unsigned char *)data;
    const int little = kdrt__little_endian();
    h->length += size;
    if (h->tail_size) {
        size_t take = 32u - h->tail_size;
        if (take > size) take = size;
        memcpy(h->tail + h->tail_size, p, take);
        h->tail_size += (uint32_t)take, p += take, size -= take;
        if (h->tail_size < 32u) return;
        kdrt__hash_stripes(h, h->tail, 1, little);
        h->tail_size = 0;
    }
    kdrt__hash_stripes(h, p, size / 32u, little);
    p += size / 32u * 32u, size %= 32u;
    if (size) memcpy(h->tail, p, size), h->tail_size = (uint32_t)size;
}

static uint64_t kdrt__xxh_merge(uint64_t acc, uint64_t v)
{
    acc ^= kdrt__xxh_round(0, v);
    return acc * (uint64_t)KDRT__P1 + (uint64_t)KDRT__P4;
}

static uint64_t kdrt__hash_end(const kdrt__hash *h)
{
    const unsigned char *p = h->tail, *end = h->tail + h->tail_size;
    uint64_t x;
    int k;
    if (h->length >= 32u) {
        x = kdrt__rotl64(h->v[0], 1) + kdrt__rotl64(h->v[1], 7) + kdrt__rotl64(h->v[2], 12) +
            kdrt__rotl64(h->v[3], 18);
        for (k = 0; k < 4; ++k) x = kdrt__xxh_merge(x, h->v[k]);
    } else {
        x = (uint64_t)KDRT__P5;
    }
    x += h->length;
    for (; p + 8 <= end; p += 8)
        x = kdrt__rotl64(x ^ kdrt__xxh_round(0, kdrt__get64(p)), 27) * (uint64_t)KDRT__P1 +
            (uint64_t)KDRT__P4;
    if (p + 4 <= end) {
        x ^= (uint64_t)kdrt__get32(p) * (uint64_t)KDRT__P1;
        x = kdrt__rotl64(x, 23) * (uint64_t)KDRT__P2 + (uint64_t)KDRT__P3;
        p += 4;
    }
    for (; p < end; ++p)
        x = kdrt__rotl64(x ^ (uint64_t)*p * (uint64_t)KDRT__P5, 11) * (uint64_t)KDRT__P1;
    x ^= x >> 33, x *= (uint64_t)KDRT__P2;
    x ^= x >> 29, x *= (uint64_t)KDRT__P3;
    return x ^ (x >> 32);
}

/* count 32-bit words from memory (floats or uint32), hashed as their little-endian bytes. */
static void kdrt__hash_words(kdrt__hash *h, const void *words, size_t count)
{
    uint32_t buffer[256];
    const unsigned char *p = (const unsigned char *)words;
    if (kdrt__little_endian()) {
        kdrt__hash_bytes(h, words, count * 4u);
        return;
    }
    while (count) {
        const size_t n = count < 256u ? count : 256u;
        size_t i;
        memcpy(buffer, p, n * 4u);
        for (i = 0; i < n; ++i) buffer[i] = kdrt__swap32(buffer[i]);
        kdrt__hash_bytes(h, buffer, n * 4u);
        p += n * 4u, count -= n;
    }
}

/* A mesh's fingerprint: XXH64 of its vertices' x, y, z floats (vertex_count of them, in order,
   whatever the stride) and XXH64 of its indices (none for a soup), each as little-endian words.
   Nothing is read from a mesh of no triangles, whose buffers may be NULL. */
static void kdrt__mesh_hashes(const kdrt_triangles *m, uint64_t *positions, uint64_t *indices)
{
    kdrt__hash h;
    kdrt__hash_init(&h);
    if (m->triangle_count && m->position_stride == 3 * sizeof(float)) {
        kdrt__hash_words(&h, m->positions, (size_t)m->vertex_count * 3u);
    } else if (m->triangle_count) {
        float buffer[3 * 128];
        const unsigned char *base = (const unsigned char *)m->positions;
        uint32_t v = 0;
        while (v < m->vertex_count) {
            const uint32_t n = m->vertex_count - v < 128u ? m->vertex_count - v : 128u;
            uint32_t i;
            for (i = 0; i < n; ++i)
                memcpy(buffer + 3 * i, base + (size_t)(v + i) * m->position_stride,
                       3 * sizeof(float));
            kdrt__hash_words(&h, buffer, (size_t)n * 3u);
            v += n;
        }
    }
    *positions = kdrt__hash_end(&h);
    kdrt__hash_init(&h);
    if (m->triangle_count && m->indices)
        kdrt__hash_words(&h, m->indices, (size_t)m->triangle_count * 3u);
    *indices = kdrt__hash_end(&h);
}

/* The sections' checksum: a Fletcher sum over the stream of 32-bit little-endian words, in eight
   lanes (word i of the stream goes to lane i mod 8: a[lane] += word, then b[lane] += a[lane],
   both 32-bit, wrapping), ended by XXH64 of a[0..7], b[0..7] (little-endian 32-bit) and the
   word count (64-bit). A word changed always changes a; words moved change b. Two additions a
   word, eight lanes at once with SSE2: the load spends next to nothing on it. */
typedef struct kdrt__sum {
    uint32_t a[8], b[8];
    uint64_t words;
} kdrt__sum;

static void kdrt__sum_word(kdrt__sum *s, uint32_t w)
{
    const size_t lane = (size_t)(s->words % 8u);
    s->a[lane] += w, s->b[lane] += s->a[lane], s->words += 1u;
}

static void kdrt__sum_words(kdrt__sum *s, const void *data, size_t count)
{
    const unsigned char *p = (const unsigned char *)data;
    const int little = kdrt__little_endian();
    for (; count > 0 && s->words % 8u != 0; --count, p += 4) /* to lane 0 again */
        kdrt__sum_word(s, kdrt__get32(p));
#if defined(KDRT__SSE2)
    {
        __m128i a0 = _mm_loadu_si128((const __m128i *)(const void *)s->a);
        __m128i a1 = _mm_loadu_si128((const __m128i *)(const void *)(s->a + 4));
        __m128i b0 = _mm_loadu_si128((const __m128i *)(const void *)s->b);
        __m128i b1 = _mm_loadu_si128((const __m128i *)(const void *)(s->b + 4));
        const size_t groups = count / 8u;
        size_t g;
        for (g = 0; g < groups; ++g, p += 32) { /* x86 is little-endian */
            a0 = _mm_add_epi32(a0, _mm_loadu_si128((const __m128i *)(const void *)p));
            a1 = _mm_add_epi32(a1, _mm_loadu_si128((const __m128i *)(const void *)(p + 16)));
            b0 = _mm_add_epi32(b0, a0);
            b1 = _mm_add_epi32(b1, a1);
        }
        _mm_storeu_si128((__m128i *)(void *)s->a, a0);
        _mm_storeu_si128((__m128i *)(void *)(s->a + 4), a1);
        _mm_storeu_si128((__m128i *)(void *)s->b, b0);
        _mm_storeu_si128((__m128i *)(void *)(s->b + 4), b1);
        s->words += (uint64_t)groups * 8u, count -= groups * 8u;
        (void)little;
    }
#else
    for (; count >= 8u; count -= 8u, p += 32) {
        uint32_t w[8];
        int k;
        memcpy(w, p, sizeof w);
        for (k = 0; k < 8; ++k) {
            s->a[k] += little ? w[k] : kdrt__swap32(w[k]);
            s->b[k] += s->a[k];
        }
        s->words += 8u;
    }
#endif
    for (; count > 0; --count, p += 4) kdrt__sum_word(s, kdrt__get32(p));
}

/* count words of memory summed as the file holds them: little-endian. */
static void kdrt__sum_memory(kdrt__sum *s, const void *words, size_t count)
{
    uint32_t buffer[256];
    const unsigned char *p = (const unsigned char *)words;
    if (kdrt__little_endian()) {
        kdrt__sum_words(s, words, count);
        return;
    }
    while (count) {
        const size_t n = count < 256u ? count : 256u;
        size_t i;
        for (i = 0; i < n; ++i) {
            uint32_t w;
            memcpy(&w, p + 4 * i, 4);
            kdrt__put32((unsigned char *)(buffer + i), w);
        }
        kdrt__sum_words(s, buffer, n);
        p += n * 4u, count -= n;
    }
}

static uint64_t kdrt__sum_end(const kdrt__sum *s)
{
    unsigned char bytes[72];
    kdrt__hash h;
    int k;
    for (k = 0; k < 8; ++k) kdrt__put32(bytes + 4 * k, s->a[k]), kdrt__put32(bytes + 32 + 4 * k, s->b[k]);
    kdrt__put64(bytes + 64, s->words);
    kdrt__hash_init(&h);
    kdrt__hash_bytes(&h, bytes, sizeof bytes);
    return kdrt__hash_end(&h);
}

/* The header: KDRT__HEADER_BYTES, fields at these offsets (the manual's table). */
#define KDRT__HEADER_BYTES 256u
/* The sections in the order of the file: blocks first, 64-byte aligned in a 64-byte aligned
   buffer, so that a load may leave them where they are (KDRT_LOAD_IN_PLACE). */
static const int kdrt__file_order[6] = {2, 1, 4, 3, 5, 0};
#define KDRT__MESH_RECORD_BYTES 32u
#define KDRT__SECTIONS 6
#define KDRT__ORDER_MARK 0x01020304u
/* Sections are hashed and compared in pieces of this many bytes, each piece still in the cache
   for its second look. */
#define KDRT__PIECE 16384u
static const unsigned char kdrt__magic[8] = {'K', 'D', 'R', 'T', 'T', 'R', 'E', 'E'};
/* Bytes a record of each section: meshes, nodes, blocks, block references, cells, cell map. */
static const uint32_t kdrt__record_bytes[KDRT__SECTIONS] = {
    KDRT__MESH_RECORD_BYTES, sizeof(kdrt__node), sizeof(kdrt__block), 4u, sizeof(kdrt__cell), 4u};

/* A saved tree's header, read and checked. */
typedef struct kdrt__file {
    const unsigned char *bytes;
    uint32_t meshes, nodes, leaves, blocks, triangles, max_depth, mesh_triangles, depth_limit;
    uint64_t refs, size, meshes_hash, tree_hash;
    uint64_t offset[KDRT__SECTIONS], count[KDRT__SECTIONS];
    kdrt_build_options options;
    kdrt_aabb bounds;
} kdrt__file;

/* The counts behind the sections of a tree (NULL: a scene without meshes). */
static void kdrt__section_counts(const kdrt_tree *tree, uint64_t count[KDRT__SECTIONS])
{
    memset(count, 0, KDRT__SECTIONS * sizeof *count);
    if (!tree) return;
    count[0] = tree->meshes.count, count[1] = tree->stats.nodes, count[2] = tree->stats.blocks;
    count[3] = tree->stats.blocks, count[4] = tree->stats.leaves, count[5] = tree->stats.nodes;
}

/* The tree's sections 1 to 5 in memory, and their sizes in bytes. */
static void kdrt__sections(const kdrt_tree *tree, const void *section[KDRT__SECTIONS],
                           size_t bytes[KDRT__SECTIONS])
{
    uint64_t count[KDRT__SECTIONS];
    int k;
    kdrt__section_counts(tree, count);
    for (k = 0; k < KDRT__SECTIONS; ++k) bytes[k] = (size_t)count[k] * kdrt__record_bytes[k];
    section[0] = NULL, section[1] = tree->nodes, section[2] = tree->blocks;
    section[3] = tree->block_refs, section[4] = tree->cells, section[5] = tree->cell_of;
}

static uint64_t kdrt__saved_bytes(const uint64_t count[KDRT__SECTIONS])
{
    uint64_t bytes = KDRT__HEADER_BYTES;
    int k;
    for (k = 0; k < KDRT__SECTIONS; ++k) bytes += count[k] * kdrt__record_bytes[k];
    return bytes;
}

/* Mesh record i of tree: its ID, counts, whether it has indices, and its fingerprint. */
static void kdrt__mesh_record(const kdrt_tree *tree, uint32_t i,
                              unsigned char out[KDRT__MESH_RECORD_BYTES])
{
    const kdrt__part *part = &tree->meshes.parts[i];
    uint64_t positions, indices;
    kdrt__mesh_hashes(&part->mesh, &positions, &indices);
    kdrt__put32(out, part->id);
    kdrt__put32(out + 4, part->mesh.triangle_count);
    kdrt__put32(out + 8, part->mesh.vertex_count);
    kdrt__put32(out + 12, part->mesh.indices ? 1u : 0u);
    kdrt__put64(out + 16, positions);
    kdrt__put64(out + 24, indices);
}

/* The header of tree (NULL: of no meshes, built with opt) into out, with the hashes of its
   sections: meshes_hash of the mesh records, tree_hash of the sections after them. */
static void kdrt__write_header(const kdrt_tree *tree, const kdrt_build_options *opt,
                               uint32_t depth_limit, uint64_t meshes_hash, uint64_t tree_hash,
                               unsigned char out[KDRT__HEADER_BYTES])
{
    uint64_t count[KDRT__SECTIONS];
    kdrt__hash h;
    kdrt_aabb box = tree ? tree->bounds : kdrt_aabb_empty();
    int k;
    kdrt__section_counts(tree, count);
    memset(out, 0, KDRT__HEADER_BYTES);
    memcpy(out, kdrt__magic, sizeof kdrt__magic);
    kdrt__put32(out + 8, KDRT__ORDER_MARK);
    kdrt__put32(out + 12, KDRT_SAVED_TREE_VERSION);
    kdrt__put32(out + 16, KDRT__HEADER_BYTES);
    kdrt__put32(out + 20, (uint32_t)count[0]);
    kdrt__put64(out + 24, kdrt__saved_bytes(count));
    for (k = 0; k < KDRT__SECTIONS; ++k)
        kdrt__put64(out + 32 + 8 * k, count[k] * kdrt__record_bytes[k]);
    if (tree) {
        kdrt__put32(out + 80, tree->stats.nodes);
        kdrt__put32(out + 84, tree->stats.leaves);
        kdrt__put32(out + 88, tree->stats.blocks);
        kdrt__put32(out + 92, tree->stats.triangles);
        kdrt__put64(out + 96, tree->stats.triangle_refs);
        kdrt__put32(out + 104, tree->stats.max_depth);
        kdrt__put32(out + 108, tree->meshes.triangles);
    }
    kdrt__put32(out + 112, (uint32_t)opt->builder);
    kdrt__put32(out + 116, (uint32_t)opt->quality);
    kdrt__put32(out + 120, (uint32_t)opt->intersector);
    kdrt__put32(out + 124, opt->max_leaf_size);
    kdrt__put32(out + 128, opt->max_depth);
    kdrt__put32(out + 132, depth_limit);
    kdrt__put32(out + 136, opt->flags & (uint32_t)KDRT_BUILD_SKIP_INVALID_TRIANGLES);
    kdrt__put32(out + 140, kdrt__float_bits(opt->sah_traversal_cost));
    kdrt__put32(out + 144, kdrt__float_bits(opt->sah_intersection_cost));
    kdrt__put32(out + 148, kdrt__float_bits(opt->sah_empty_bonus));
    kdrt__put32(out + 152, KDRT_SAH_BINS);
    kdrt__put32(out + 156, KDRT_SAH_EXACT_MAX);
    kdrt__put32(out + 160, KDRT_SAH_REFERENCE_BUDGET);
    for (k = 0; k < 3; ++k) {
        kdrt__put32(out + 164 + 4 * k, kdrt__float_bits(box.min[k]));
        kdrt__put32(out + 176 + 4 * k, kdrt__float_bits(box.max[k]));
    }
    /* 188 and 208 to 247: reserved, 0 */
    kdrt__put64(out + 192, meshes_hash);
    kdrt__put64(out + 200, tree_hash);
    kdrt__hash_init(&h);
    kdrt__hash_bytes(&h, out, KDRT__HEADER_BYTES - 8u);
    kdrt__put64(out + KDRT__HEADER_BYTES - 8u, kdrt__hash_end(&h));
}

/* The bounds a tree of `triangles` usable ones may have: kdrt_aabb_empty()'s bits with none,
   else a finite box. */
static int kdrt__bounds_ok(const kdrt_aabb *b, uint32_t triangles)
{
    const kdrt_aabb empty = kdrt_aabb_empty();
    int a;
    if (triangles == 0) return memcmp(b, &empty, sizeof empty) == 0;
    for (a = 0; a < 3; ++a)
        if (!kdrt__finite(b->min[a]) || !kdrt__finite(b->max[a]) || !(b->min[a] <= b->max[a]))
            return 0;
    return 1;
}

/* Reads and checks the header of the size bytes at bytes: the magic, byte order, version and
   checksum first (each with its own result), then every field, the sections' sizes against
   their counts and the file's size. */
static kdrt_result kdrt__read_header(const void *data, size_t size, kdrt__file *f)
{
    const unsigned char *p = (const unsigned char *)data;
    kdrt__hash h;
    uint64_t total = KDRT__HEADER_BYTES;
    uint32_t bins, budget, reserved;
    int k;
    memset(f, 0, sizeof *f);
    if (!data) return KDRT_ERROR_NULL_ARGUMENT;
    if (memcmp(p, kdrt__magic, size < 8u ? size : 8u) != 0) return KDRT_ERROR_NOT_A_SAVED_TREE;
    if (size < 16u) return KDRT_ERROR_FILE_SIZE; /* a magic's start, or the magic alone */
    if (kdrt__get32(p + 8) != KDRT__ORDER_MARK) {
        if (kdrt__get32(p + 8) == kdrt__swap32(KDRT__ORDER_MARK)) return KDRT_ERROR_FILE_BYTE_ORDER;
        return KDRT_ERROR_FILE_CORRUPT;
    }
    if (kdrt__get32(p + 12) != KDRT_SAVED_TREE_VERSION) return KDRT_ERROR_FILE_VERSION;
    if (size < KDRT__HEADER_BYTES) return KDRT_ERROR_FILE_SIZE;
    kdrt__hash_init(&h);
    kdrt__hash_bytes(&h, p, KDRT__HEADER_BYTES - 8u);
    if (kdrt__hash_end(&h) != kdrt__get64(p + KDRT__HEADER_BYTES - 8u))
        return KDRT_ERROR_FILE_CORRUPT;
    /* The checksum holds: every field as a save wrote it, unless the file was forged. */
    f->bytes = p;
    f->meshes = kdrt__get32(p + 20);
    f->size = kdrt__get64(p + 24);
    f->nodes = kdrt__get32(p + 80), f->leaves = kdrt__get32(p + 84);
    f->blocks = kdrt__get32(p + 88), f->triangles = kdrt__get32(p + 92);
    f->refs = kdrt__get64(p + 96), f->max_depth = kdrt__get32(p + 104);
    f->mesh_triangles = kdrt__get32(p + 108);
    f->options.builder = (kdrt_builder)kdrt__get32(p + 112);
    f->options.quality = (kdrt_build_quality)kdrt__get32(p + 116);
    f->options.intersector = (kdrt_intersector)kdrt__get32(p + 120);
    f->options.max_leaf_size = kdrt__get32(p + 124);
    f->options.max_depth = kdrt__get32(p + 128);
    f->depth_limit = kdrt__get32(p + 132);
    f->options.flags = kdrt__get32(p + 136);
    f->options.sah_traversal_cost = kdrt__bits_float(kdrt__get32(p + 140));
    f->options.sah_intersection_cost = kdrt__bits_float(kdrt__get32(p + 144));
    f->options.sah_empty_bonus = kdrt__bits_float(kdrt__get32(p + 148));
    bins = kdrt__get32(p + 152), budget = kdrt__get32(p + 160);
    /* 156, KDRT_SAH_EXACT_MAX: any value is one it may take */
    for (k = 0; k < 3; ++k) {
        f->bounds.min[k] = kdrt__bits_float(kdrt__get32(p + 164 + 4 * k));
        f->bounds.max[k] = kdrt__bits_float(kdrt__get32(p + 176 + 4 * k));
    }
    reserved = kdrt__get32(p + 188);
    f->meshes_hash = kdrt__get64(p + 192), f->tree_hash = kdrt__get64(p + 200);
    f->count[0] = f->meshes, f->count[1] = f->nodes, f->count[2] = f->blocks;
    f->count[3] = f->blocks, f->count[4] = f->leaves, f->count[5] = f->nodes;
    for (k = 0; k < KDRT__SECTIONS; ++k) {
        const int section = kdrt__file_order[k];
        if (kdrt__get64(p + 32 + 8 * section) != f->count[section] * kdrt__record_bytes[section])
            return KDRT_ERROR_FILE_CORRUPT;
        f->offset[section] = total;
        total += f->count[section] * kdrt__record_bytes[section]; /* counts < 2^32: no overflow */
    }
    for (k = 208; k < (int)KDRT__HEADER_BYTES - 8; k += 4) reserved |= kdrt__get32(p + k);
    if (kdrt__get32(p + 16) != KDRT__HEADER_BYTES || total != f->size || reserved != 0)
        return KDRT_ERROR_FILE_CORRUPT;
    if (kdrt__check_options(&f->options) != KDRT_SUCCESS ||
        (f->options.flags & ~(uint32_t)KDRT_BUILD_SKIP_INVALID_TRIANGLES) || bins < 2u ||
        bins > 1024u || budget < 1u || budget > 64u || f->depth_limit > KDRT_MAX_DEPTH ||
        f->depth_limit != (f->options.max_depth == 0 ? kdrt__default_depth(f->mesh_triangles)
                           : f->options.max_depth < KDRT_MAX_DEPTH ? f->options.max_depth
                                                                   : KDRT_MAX_DEPTH))
        return KDRT_ERROR_FILE_CORRUPT;
    if (f->meshes == 0) {
        /* A scene without meshes: nothing else. */
        if (f->nodes || f->leaves || f->blocks || f->triangles || f->refs || f->max_depth ||
            f->mesh_triangles || !kdrt__bounds_ok(&f->bounds, 0))
            return KDRT_ERROR_FILE_CORRUPT;
    } else if (f->nodes == 0 || f->nodes % 2u == 0 || f->leaves != f->nodes / 2u + 1u ||
               f->triangles > f->mesh_triangles || f->mesh_triangles > KDRT_MAX_TRIANGLES ||
               (f->triangles == 0) != (f->refs == 0) || f->refs > 0xFFFFFFFFu ||
               f->blocks > f->refs || f->refs > (uint64_t)f->blocks * KDRT__LANES ||
               f->max_depth > f->depth_limit || !kdrt__bounds_ok(&f->bounds, f->triangles)) {
        return KDRT_ERROR_FILE_CORRUPT;
    }
    if (f->size != size) return KDRT_ERROR_FILE_SIZE;
    return KDRT_SUCCESS;
}

/* The file's mesh records (hashed first: a damaged one is a corrupt file) against the meshes
   given: KDRT_ERROR_MESH_MISMATCH, with *bad the index of the first that differs (count when
   their numbers differ). */
static kdrt_result kdrt__check_meshes(const kdrt__file *f, const kdrt__meshes *m, uint32_t *bad)
{
    kdrt__hash h;
    uint32_t i;
    *bad = m->count;
    kdrt__hash_init(&h);
    kdrt__hash_bytes(&h, f->bytes + f->offset[0], (size_t)f->meshes * KDRT__MESH_RECORD_BYTES);
    if (kdrt__hash_end(&h) != f->meshes_hash) return KDRT_ERROR_FILE_CORRUPT;
    if (f->meshes != m->count) return KDRT_ERROR_MESH_MISMATCH;
    for (i = 0; i < m->count; ++i) {
        const unsigned char *r = f->bytes + f->offset[0] + (size_t)i * KDRT__MESH_RECORD_BYTES;
        const kdrt_triangles *mesh = &m->parts[i].mesh;
        uint64_t positions, indices;
        *bad = i;
        if (kdrt__get32(r) != m->parts[i].id || kdrt__get32(r + 4) != mesh->triangle_count ||
            kdrt__get32(r + 8) != mesh->vertex_count ||
            kdrt__get32(r + 12) != (mesh->indices ? 1u : 0u))
            return KDRT_ERROR_MESH_MISMATCH;
        kdrt__mesh_hashes(mesh, &positions, &indices);
        if (kdrt__get64(r + 16) != positions || kdrt__get64(r + 24) != indices)
            return KDRT_ERROR_MESH_MISMATCH;
    }
    *bad = m->count;
    /* The same records give the same total (a forged header may say otherwise). */
    return f->mesh_triangles == m->triangles ? KDRT_SUCCESS : KDRT_ERROR_FILE_CORRUPT;
}

/* count words of the file at in into memory at out. */
static void kdrt__copy_words(void *out, const unsigned char *in, size_t words)
{
    if (words == 0) return;
    memcpy(out, in, words * 4u);
    if (!kdrt__little_endian()) {
        uint32_t *w = (uint32_t *)out;
        size_t i;
        for (i = 0; i < words; ++i) w[i] = kdrt__swap32(w[i]);
    }
}

/* The nodes, and the sections made from them, checked in one pass over the file's nodes in
   array order, which must be the depth-first order a build lays them out in: each inner node's
   below child next, its above child further on and reached exactly when the below subtree ends,
   so that no index repeats and there is no cycle; depth at most the file's depth limit; each
   split finite and within its node's box (the tree's bounds cut by the ancestors' splits); each
   leaf's first block the count of blocks before it, and the counts of leaves, blocks, references
   and the deepest leaf the header's. The file's block references, cells and cell map are checked
   against the same walk: each block's first reference, each cell's box bit for bit and its ropes
   nodes of the tree (or none), each node's entry in the map. The SAH cost adds up on the way, as
   kdrt__sah_cost adds it (the same order and operations). */
static kdrt_result kdrt__check_nodes(kdrt_tree *tree, const kdrt__file *f, double trav,
                                     double isect)
{
    struct { uint32_t node, depth; float lo[3], hi[3]; } stack[KDRT_MAX_DEPTH + 1], at;
    const unsigned char *nodes_in = f->bytes + f->offset[1], *refs_in = f->bytes + f->offset[3];
    const unsigned char *cells_in = f->bytes + f->offset[4], *map_in = f->bytes + f->offset[5];
    const double root_area = kdrt__half_area(f->bounds.min, f->bounds.max);
    const int costed = f->triangles != 0 && root_area > 0.0;
    double cost = 0.0;
    uint32_t i, sp = 0, leaves = 0, blocks = 0, deepest = 0, k;
    uint64_t refs = 0;
    at.node = 0, at.depth = 0;
    memcpy(at.lo, f->bounds.min, sizeof at.lo), memcpy(at.hi, f->bounds.max, sizeof at.hi);
    for (i = 0; i < f->nodes; ++i) {
        kdrt__node node, *n = &node;
        const double share = costed ? kdrt__half_area(at.lo, at.hi) / root_area : 0.0;
        n->u.first = kdrt__get32(nodes_in + 8 * (size_t)i);
        n->bits = kdrt__get32(nodes_in + 8 * (size_t)i + 4u);
        if (at.node != i || at.depth > f->depth_limit) return KDRT_ERROR_FILE_CORRUPT;
        if (kdrt__node_is_leaf(n)) {
            const uint32_t count = kdrt__node_count(n);
            const uint32_t used = (count + KDRT__LANES - 1u) / KDRT__LANES;
            const unsigned char *cell = cells_in + (size_t)leaves * sizeof(kdrt__cell);
            if (n->u.first != blocks || used > f->blocks - blocks || leaves >= f->leaves ||
                kdrt__get32(map_in + 4 * (size_t)i) != leaves)
                return KDRT_ERROR_FILE_CORRUPT;
            for (k = 0; k < used; ++k)
                if (kdrt__get32(refs_in + 4 * ((size_t)blocks + k)) !=
                    (uint32_t)refs + k * KDRT__LANES)
                    return KDRT_ERROR_FILE_CORRUPT;
            for (k = 0; k < 3; ++k)
                if (kdrt__get32(cell + 4 * k) != kdrt__float_bits(at.lo[k]) ||
                    kdrt__get32(cell + 12 + 4 * k) != kdrt__float_bits(at.hi[k]))
                    return KDRT_ERROR_FILE_CORRUPT;
            for (k = 0; k < 6; ++k) {
                const uint32_t rope = kdrt__get32(cell + 24 + 4 * k);
                if (rope >= f->nodes && rope != KDRT__NO_ROPE) return KDRT_ERROR_FILE_CORRUPT;
            }
            cost += share * isect * kdrt__leaf_blocks(count);
            blocks += used, refs += count, ++leaves;
            if (refs > f->refs) return KDRT_ERROR_FILE_CORRUPT;
            if (at.depth > deepest) deepest = at.depth;
            if (sp == 0) {
                at.node = KDRT__NO_ROPE; /* the walk is over: no node may follow */
                continue;
            }
            at = stack[--sp];
        } else {
            const uint32_t axis = kdrt__node_axis(n), above = kdrt__node_above(n);
            const float split = n->u.split;
            if (above <= i + 1u || above >= f->nodes || !kdrt__finite(split) ||
                !(at.lo[axis] <= split && split <= at.hi[axis]) || sp >= KDRT_MAX_DEPTH ||
                kdrt__get32(map_in + 4 * (size_t)i) != KDRT__NO_ROPE)
                return KDRT_ERROR_FILE_CORRUPT;
            cost += share * trav;
            stack[sp] = at; /* the above child, reached when the below subtree ends */
            stack[sp].node = above, stack[sp].depth = at.depth + 1u;
            stack[sp++].lo[axis] = split;
            at.node = i + 1u, at.depth += 1u;
            at.hi[axis] = split;
        }
    }
    if (at.node != KDRT__NO_ROPE || leaves != f->leaves || blocks != f->blocks ||
        refs != f->refs || deepest != f->max_depth)
        return KDRT_ERROR_FILE_CORRUPT;
    tree->stats.sah_cost = costed ? cost : isect * kdrt__leaf_blocks(f->refs);
    return KDRT_SUCCESS;
}

/* The blocks, summed into s and checked, copied first a piece at a time unless the tree uses
   them in place: every lane's triangle below the meshes' count, and a leaf's last block filled up
   as the build fills it, with copies of its last triangle (its number and its corners). The
   lanes' counts come from the checked nodes, read from the file. */
static kdrt_result kdrt__load_blocks(kdrt_tree *tree, const kdrt__file *f, kdrt__sum *s)
{
    const unsigned char *in = f->bytes + f->offset[2], *nodes_in = f->bytes + f->offset[1];
    const uint32_t triangles = tree->meshes.triangles, piece = KDRT__PIECE / sizeof(kdrt__block);
    uint32_t node = 0, left = 0, b, end;
    for (b = 0; b < f->blocks; b = end) {
        end = f->blocks - b < piece ? f->blocks : b + piece;
        if (tree->block_memory)
            kdrt__copy_words(&tree->blocks[b], in + (size_t)b * sizeof(kdrt__block),
                             (size_t)(end - b) * (sizeof(kdrt__block) / 4u));
        kdrt__sum_words(s, in + (size_t)b * sizeof(kdrt__block),
                        (size_t)(end - b) * (sizeof(kdrt__block) / 4u));
        for (; b < end; ++b) {
            const kdrt__block *block = &tree->blocks[b];
            uint32_t real, lane, c;
            while (left == 0) { /* the next leaf with triangles: the checked nodes have them */
                const uint32_t bits = kdrt__get32(nodes_in + 8 * (size_t)node++ + 4u);
                if ((bits & 3u) == KDRT__LEAF) left = bits >> 2;
            }
            real = left < KDRT__LANES ? left : KDRT__LANES;
            left -= real;
            for (lane = 0; lane < real; ++lane)
                if (block->id[lane] >= triangles) return KDRT_ERROR_FILE_CORRUPT;
            for (; lane < KDRT__LANES; ++lane) {
                if (block->id[lane] != block->id[real - 1u]) return KDRT_ERROR_FILE_CORRUPT;
                for (c = 0; c < 9; ++c)
                    if (kdrt__float_bits(block->corner[c][lane]) !=
                        kdrt__float_bits(block->corner[c][real - 1u]))
                        return KDRT_ERROR_FILE_CORRUPT;
            }
        }
    }
    return KDRT_SUCCESS;
}

/* Section k of the file summed into s, and copied to mem unless mem is the file's own. */
static void kdrt__copy_section(kdrt__sum *s, void *mem, const kdrt__file *f, int k)
{
    const unsigned char *in = f->bytes + f->offset[k];
    unsigned char *out = (unsigned char *)mem;
    size_t bytes = (size_t)f->count[k] * kdrt__record_bytes[k];
    while (bytes) {
        const size_t n = bytes < KDRT__PIECE ? bytes : KDRT__PIECE;
        if (out != in) kdrt__copy_words(out, in, n / 4u);
        kdrt__sum_words(s, in, n / 4u);
        out += n, in += n, bytes -= n;
    }
}

/* The tree's arrays from the file f over its meshes (the header and meshes checked): the nodes
   and what is made from them checked in one pass, the blocks' lanes as they are copied, each
   other section copied as it is, then the sections' checksum. In place (the flag, a 64-byte
   aligned file and a little-endian host) the arrays are the file's, nothing copied. On failure
   frees the tree. */
static kdrt_result kdrt__load_tree(kdrt_tree *tree, const kdrt__file *f, uint32_t flags)
{
    const kdrt_allocator *a = &tree->allocator;
    const float trav = f->options.sah_traversal_cost > 0.0f ? f->options.sah_traversal_cost
                                                           : KDRT_DEFAULT_SAH_TRAVERSAL_COST;
    const float isect = f->options.sah_intersection_cost > 0.0f
                            ? f->options.sah_intersection_cost
                            : KDRT_DEFAULT_SAH_INTERSECTION_COST;
    kdrt__sum s;
    kdrt_result r = KDRT_SUCCESS;
    tree->watertight = f->options.intersector != KDRT_INTERSECTOR_FAST;
    tree->shape = f->options, tree->depth_limit = f->depth_limit;
    tree->bounds = f->bounds;
    tree->stats.triangles = f->triangles, tree->stats.nodes = f->nodes;
    tree->stats.leaves = f->leaves, tree->stats.max_depth = f->max_depth;
    tree->stats.triangle_refs = f->refs, tree->stats.blocks = f->blocks;
    tree->stats.bytes = sizeof *tree;
    tree->in_place = (flags & (uint32_t)KDRT_LOAD_IN_PLACE) && kdrt__little_endian() &&
                     (uintptr_t)f->bytes % 64u == 0;
    if (tree->in_place) {
        /* The file's own sections: blocks at a multiple of 64 bytes, the rest of 4. */
        tree->blocks = (kdrt__block *)(uintptr_t)(f->bytes + f->offset[2]);
        tree->nodes = (kdrt__node *)(uintptr_t)(f->bytes + f->offset[1]);
        tree->block_refs = (uint32_t *)(uintptr_t)(f->bytes + f->offset[3]);
        tree->cells = (kdrt__cell *)(uintptr_t)(f->bytes + f->offset[4]);
        tree->cell_of = (uint32_t *)(uintptr_t)(f->bytes + f->offset[5]);
    } else {
        /* Each array is no larger than its section: memory bounded by the file's size. */
        tree->nodes = (kdrt__node *)kdrt__alloc(a, (size_t)f->nodes * sizeof(kdrt__node));
        tree->cells = (kdrt__cell *)kdrt__alloc(a, (size_t)f->leaves * sizeof(kdrt__cell));
        tree->cell_of = (uint32_t *)kdrt__alloc(a, (size_t)f->nodes * sizeof(uint32_t));
        if (f->blocks) {
            tree->block_memory = kdrt__alloc(a, (size_t)f->blocks * sizeof(kdrt__block) + 63u);
            tree->block_refs = (uint32_t *)kdrt__alloc(a, (size_t)f->blocks * sizeof(uint32_t));
        }
        if (!tree->nodes || !tree->cells || !tree->cell_of ||
            (f->blocks && (!tree->block_memory || !tree->block_refs)))
            r = KDRT_ERROR_OUT_OF_MEMORY;
        if (tree->block_memory)
            tree->blocks = (kdrt__block *)((char *)tree->block_memory +
                                           ((64u - (uintptr_t)tree->block_memory % 64u) % 64u));
        tree->stats.bytes += (size_t)f->nodes * sizeof(kdrt__node) +
                             (size_t)f->blocks * (sizeof(kdrt__block) + sizeof(uint32_t)) +
                             (tree->block_memory ? 63u : 0u) +
                             (size_t)f->leaves * sizeof(kdrt__cell) +
                             (size_t)f->nodes * sizeof(uint32_t);
    }
    memset(&s, 0, sizeof s);
    if (r == KDRT_SUCCESS) r = kdrt__check_nodes(tree, f, trav, isect);
    if (r == KDRT_SUCCESS) r = kdrt__load_blocks(tree, f, &s);
    if (r == KDRT_SUCCESS) {
        kdrt__copy_section(&s, tree->nodes, f, 1);
        kdrt__copy_section(&s, tree->cells, f, 4);
        kdrt__copy_section(&s, tree->block_refs, f, 3);
        kdrt__copy_section(&s, tree->cell_of, f, 5);
        if (kdrt__sum_end(&s) != f->tree_hash) r = KDRT_ERROR_FILE_CORRUPT;
    }
    if (r != KDRT_SUCCESS) kdrt_tree_free(tree);
    return r;
}

/* The bytes of tree (NULL: a scene without meshes, built with opt) through write: the header,
   the tree's sections in the file's order, the mesh records. The checksums come first, in the
   header: the records are made twice, hashed then written. */
static kdrt_result kdrt__save(const kdrt_tree *tree, const kdrt_build_options *opt,
                              uint32_t depth_limit, kdrt_write_fn write, void *user)
{
    unsigned char header[KDRT__HEADER_BYTES], record[KDRT__MESH_RECORD_BYTES];
    const void *section[KDRT__SECTIONS];
    size_t bytes[KDRT__SECTIONS];
    kdrt__hash meshes;
    kdrt__sum rest;
    uint32_t i;
    int k;
    if (!write) return KDRT_ERROR_NULL_ARGUMENT;
    kdrt__hash_init(&meshes);
    memset(&rest, 0, sizeof rest);
    if (tree) {
        kdrt__sections(tree, section, bytes);
        for (i = 0; i < tree->meshes.count; ++i) {
            kdrt__mesh_record(tree, i, record);
            kdrt__hash_bytes(&meshes, record, sizeof record);
        }
        for (k = 0; k < KDRT__SECTIONS - 1; ++k)
            kdrt__sum_memory(&rest, section[kdrt__file_order[k]], bytes[kdrt__file_order[k]] / 4u);
    }
    kdrt__write_header(tree, opt, depth_limit, kdrt__hash_end(&meshes), kdrt__sum_end(&rest),
                       header);
    if (!write(user, header, sizeof header)) return KDRT_ERROR_WRITE_FAILED;
    if (!tree) return KDRT_SUCCESS;
    for (k = 0; k < KDRT__SECTIONS - 1; ++k) {
        const unsigned char *p = (const unsigned char *)section[kdrt__file_order[k]];
        size_t left = bytes[kdrt__file_order[k]] / 4u;
        if (left == 0) continue;
        if (kdrt__little_endian()) {
            if (!write(user, p, left * 4u)) return KDRT_ERROR_WRITE_FAILED;
            continue;
        }
        while (left) {
            uint32_t buffer[256];
            const size_t n = left < 256u ? left : 256u;
            size_t w;
            memcpy(buffer, p, n * 4u);
            for (w = 0; w < n; ++w) buffer[w] = kdrt__swap32(buffer[w]);
            if (!write(user, buffer, n * 4u)) return KDRT_ERROR_WRITE_FAILED;
            p += n * 4u, left -= n;
        }
    }
    for (i = 0; i < tree->meshes.count; ++i) {
        kdrt__mesh_record(tree, i, record);
        if (!write(user, record, sizeof record)) return KDRT_ERROR_WRITE_FAILED;
    }
    return KDRT_SUCCESS;
}

/* A load's options: a build's, and KDRT_LOAD_IN_PLACE. */
static kdrt_result kdrt__check_load_options(const kdrt_build_options *opt)
{
    kdrt_build_options build = *opt;
    build.flags &= ~(uint32_t)KDRT_LOAD_IN_PLACE;
    return kdrt__check_options(&build);
}

KDRT_API size_t kdrt_tree_saved_size(const kdrt_tree *tree)
{
    uint64_t count[KDRT__SECTIONS];
    if (!tree) return 0;
    kdrt__section_counts(tree, count);
    return (size_t)kdrt__saved_bytes(count);
}

KDRT_API kdrt_result kdrt_tree_save(const kdrt_tree *tree, kdrt_write_fn write, void *user)
{
    if (!tree) return KDRT_ERROR_NULL_ARGUMENT;
    return kdrt__save(tree, &tree->shape, tree->depth_limit, write, user);
}

KDRT_API kdrt_result kdrt_saved_tree_read_info(const void *bytes, size_t size,
                                               kdrt_saved_tree_info *out_info)
{
    kdrt__file f;
    kdrt_result r;
    if (!out_info) return KDRT_ERROR_NULL_ARGUMENT;
    memset(out_info, 0, sizeof *out_info);
    r = kdrt__read_header(bytes, size, &f);
    if (r != KDRT_SUCCESS) return r;
    out_info->version = KDRT_SAVED_TREE_VERSION;
    out_info->size = f.size;
    out_info->meshes = f.meshes;
    out_info->mesh_triangles = f.mesh_triangles;
    out_info->options = f.options;
    out_info->depth_limit = f.depth_limit;
    out_info->bounds = f.bounds;
    out_info->stats.triangles = f.triangles, out_info->stats.nodes = f.nodes;
    out_info->stats.leaves = f.leaves, out_info->stats.max_depth = f.max_depth;
    out_info->stats.triangle_refs = f.refs, out_info->stats.blocks = f.blocks;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_tree_load(const void *bytes, size_t size, const kdrt_triangles *mesh,
                                    const kdrt_build_options *options, kdrt_tree **out_tree,
                                    kdrt_build_report *report)
{
    kdrt_build_options opt = options ? *options : kdrt_default_build_options();
    kdrt_triangles m;
    kdrt__file f;
    kdrt_tree *tree;
    uint32_t bad;
    kdrt_result r;
    kdrt__report_init(report);
    if (!out_tree) return KDRT_ERROR_NULL_ARGUMENT;
    *out_tree = NULL;
    r = kdrt__check_view(mesh, &m);
    if (r == KDRT_SUCCESS) r = kdrt__check_load_options(&opt);
    if (r == KDRT_SUCCESS) r = kdrt__read_header(bytes, size, &f);
    if (r != KDRT_SUCCESS) return r;
    opt.intersector = f.options.intersector; /* the kernel's choice as a build makes it */
    tree = kdrt__tree_new(&opt, NULL);
    if (!tree) return KDRT_ERROR_OUT_OF_MEMORY;
    tree->one.mesh = m, tree->one.mask = 0xFFFFFFFFu;
    tree->meshes.triangles = m.triangle_count;
    r = kdrt__check_meshes(&f, &tree->meshes, &bad);
    if (r != KDRT_SUCCESS) {
        kdrt_tree_free(tree);
        return r;
    }
    r = kdrt__load_tree(tree, &f, opt.flags); /* frees it on failure */
    if (r == KDRT_SUCCESS) *out_tree = tree;
    return r;
}

/* ==== scenes: meshes in one tree, instances under a top-level tree ==== */


/* The top level: a 4-wide BVH over the instances' world boxes, binned by their centres, each
   instance in one leaf (as Embree's and tinybvh's top levels are). A node holds its children's
   boxes, an axis a row, so that a ray meets all four in one slab test (4 lanes of SSE2). */
typedef struct kdrt__level_node {
    float lo[3][4], hi[3][4];
    /* A lane: count 0 the inner node first; else instances items[first .. first + count); count
       KDRT_INVALID_ID a lane not in use (its box lane 0's). */
    uint32_t first[4], count[4];
} kdrt__level_node;

/* A box padded to 4 lanes (the fourth 0, or infinite when empty), for SSE2. */
typedef struct kdrt__box4 {
    float min[4], max[4];
} kdrt__box4;

/* What the builder reads of an instance, in order rather than from the instances. */
typedef struct kdrt__level_prim {
    kdrt__box4 box;
    float centre[4];
} kdrt__level_prim;

/* A commit's top level lives in one arena, which the next commit reuses when it fits: the nodes
   (at most 2n - 1 over n instances), the order of the instances (items) and their prims. */
typedef struct kdrt__level {
    void *arena;
    size_t arena_bytes;
    kdrt__level_node *nodes; /* NULL: no instance to walk */
    uint32_t *items;       /* instance indices, a leaf's a run */
    struct kdrt__level_prim *prims; /* [instance index] */
    kdrt_aabb root;        /* the box of the instances in the nodes */
    kdrt_aabb bounds;      /* of every instance, those no query sees included */
} kdrt__level;

/* What queries see: the entries of the last commit and where each one's data lies. */
typedef struct kdrt__layout {
    kdrt_geometry *entries;    /* by ascending ID; transforms and flags as committed */
    uint32_t *slot;            /* [entry]: its index in parts (a mesh) or instances */
    kdrt__part *parts;         /* the meshes, as the mesh tree numbers them */
    kdrt__instance *instances; /* by ascending ID */
    uint32_t entry_count, part_count, instance_count;
} kdrt__layout;

struct kdrt_scene {
    kdrt_build_options options; /* the mesh tree's; its allocator and scheduler serve each commit */
    kdrt__layout now;
    kdrt_tree *meshes;          /* one tree over now's meshes; NULL when there is none */
    kdrt__level top;
    kdrt_aabb bounds;
    /* The scene from the next commit on: every entry by ascending ID, with the transforms and
       flags set since; *_changed say what the commit must redo beyond the top level. */
    kdrt_geometry *next;
    uint32_t next_count, next_capacity;
    int entries_changed, meshes_changed, moved;
    const kdrt__file *load; /* kdrt_scene_load()'s first commit: the mesh tree from this file */
};

KDRT_API kdrt_geometry kdrt_mesh_geometry(uint32_t id, const kdrt_triangles *mesh)
{
    kdrt_geometry g;
    memset(&g, 0, sizeof g);
    g.type = KDRT_GEOMETRY_MESH;
    g.id = id;
    g.mask = 0xFFFFFFFFu;
    if (mesh) g.mesh = *mesh;
    g.transform[0] = g.transform[5] = g.transform[10] = 1.0f;
    return g;
}

KDRT_API kdrt_geometry kdrt_instance_geometry(uint32_t id, const kdrt_tree *tree,
                                              const float transform[12])
{
    kdrt_geometry g = kdrt_mesh_geometry(id, NULL);
    g.type = KDRT_GEOMETRY_INSTANCE;
    g.tree = tree;
    if (transform) memcpy(g.transform, transform, sizeof g.transform);
    return g;
}

/* An instance of tree placed by transform: KDRT_ERROR_INVALID_TRANSFORM for a NaN or infinite
   entry, a matrix so near singular that its inverse means nothing (|det R| under 2^-40 of the
   product of its rows' lengths: 1 for a rotation, whatever the scales), or a world box beyond
   float's range. */
static kdrt_result kdrt__place_instance(const kdrt_tree *tree, const float transform[12],
                                        kdrt__instance *in)
{
    const double *m = in->to_world;
    double det, rows = 1.0, *inv = in->to_object;
    int i, j;
    for (i = 0; i < 12; ++i) {
        if (!kdrt__finite(transform[i])) return KDRT_ERROR_INVALID_TRANSFORM;
        in->to_world[i] = transform[i];
    }
    /* The adjugate of R over its determinant; R's rows are m[0..2], m[4..6], m[8..10]. */
    inv[0] = m[5] * m[10] - m[6] * m[9], inv[1] = m[2] * m[9] - m[1] * m[10];
    inv[2] = m[1] * m[6] - m[2] * m[5], inv[3] = m[6] * m[8] - m[4] * m[10];
    inv[4] = m[0] * m[10] - m[2] * m[8], inv[5] = m[2] * m[4] - m[0] * m[6];
    inv[6] = m[4] * m[9] - m[5] * m[8], inv[7] = m[1] * m[8] - m[0] * m[9];
    inv[8] = m[0] * m[5] - m[1] * m[4];
    det = m[0] * inv[0] + m[1] * inv[3] + m[2] * inv[6];
    for (i = 0; i < 3; ++i)
        rows *= sqrt(m[4 * i] * m[4 * i] + m[4 * i + 1] * m[4 * i + 1] + m[4 * i + 2] * m[4 * i + 2]);
    /* A zero row makes both sides 0: det must be nonzero as well. */
    if (!(fabs(det) > 0.0 && fabs(det) >= 9.094947017729282e-13 /* 2^-40 */ * rows) ||
        det - det != 0.0)
        return KDRT_ERROR_INVALID_TRANSFORM;
    for (i = 0; i < 9; ++i) inv[i] /= det;
    in->tree = tree;
    in->mirrored = det < 0.0;
    in->box = kdrt_aabb_empty();
    if (tree->bounds.min[0] <= tree->bounds.max[0]) {
        /* The tree's box in the world from its centre and half extent (Arvo): centre carried by
           [R | t], half extent by |R|, in double; then widened by 2^-20 of the box's extent and
           position on each axis: a ray's trip into the tree's space is rounded, and the top
           level must not cull an instance that ray would hit. */
        double c[3], e[3];
        for (j = 0; j < 3; ++j) {
            c[j] = 0.5 * ((double)tree->bounds.min[j] + tree->bounds.max[j]);
            e[j] = 0.5 * ((double)tree->bounds.max[j] - tree->bounds.min[j]);
        }
        for (i = 0; i < 3; ++i) {
            const double *row = &m[4 * i];
            const double x = row[0] * c[0] + row[1] * c[1] + row[2] * c[2] + row[3];
            const double h = fabs(row[0]) * e[0] + fabs(row[1]) * e[1] + fabs(row[2]) * e[2];
            const double pad = 9.5367431640625e-7 /* 2^-20 */ * (2.0 * h + fabs(x) + h);
            in->box.min[i] = kdrt__float_down(x - h - pad);
            in->box.max[i] = kdrt__float_up(x + h + pad);
            /* A box beyond float's range has no finite planes to bin by: refused. */
            if (!kdrt__finite(in->box.min[i]) || !kdrt__finite(in->box.max[i]))
                return KDRT_ERROR_INVALID_TRANSFORM;
        }
    }
    return KDRT_SUCCESS;
}

/* ---- the top level: a binned BVH over the instances' boxes ---- */

/* Its SAH costs, a node step against an instance's (a slab test of its world box, and for the
   ray that meets it a trip into its space and a walk of its tree). */
#define KDRT__LEVEL_TRAVERSAL_COST 1.0
#define KDRT__LEVEL_INSTANCE_COST 8.0
#define KDRT__LEVEL_BINS 16u      /* bins an axis, over the centres of a node's boxes */
#define KDRT__LEVEL_MAX_LEAF 8u   /* more instances are split even when the SAH would not */
#define KDRT__LEVEL_MAX_DEPTH 32u /* nodes deep; below that, leaves */
#define KDRT__LEVEL_STACK (3u * KDRT__LEVEL_MAX_DEPTH + 4u) /* a node pops 1 and pushes 4 */
/* From this many instances, the top level's subtrees and the instances' placing run on
   options.scheduler; below it, a task costs more than it saves. */
#define KDRT__LEVEL_PARALLEL_MIN 2048u
#define KDRT__LEVEL_TASKS 64u

typedef struct kdrt__level_task {
    uint32_t node, begin, end, children, depth;
    kdrt_aabb box;
} kdrt__level_task;

typedef struct kdrt__level_builder {
    kdrt__level_node *nodes;
    uint32_t *items;
    const kdrt__level_prim *prims;
    /* The parallel build's first pass leaves subtrees of at most task_size instances here. */
    kdrt__level_task *tasks;
    uint32_t task_count, task_size;
} kdrt__level_builder;

/* The bin of centre c among bins over [lo, lo + bins / scale], clamped to them (a NaN from
   an overflowing difference too). The split and the sort into children both call it, so they
   agree. */
static uint32_t kdrt__level_bin(float c, float lo, float scale, uint32_t bins)
{
    float f = (c - lo) * scale;
    f = f > 0.0f ? f : 0.0f;
    f = f < (float)(bins - 1u) ? f : (float)(bins - 1u);
    return (uint32_t)f;
}

/* kdrt__level_bin of a centre on the three axes at once (SSE2: the same operations a lane). */
static KDRT__FORCEINLINE void kdrt__level_bins(const float c[4], const float lo[4],
                                               const float scale[4], uint32_t bins, uint32_t k[4])
{
#if KDRT__SSE2
    __m128 f = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(c), _mm_loadu_ps(lo)), _mm_loadu_ps(scale));
    f = _mm_min_ps(_mm_max_ps(f, _mm_setzero_ps()), _mm_set1_ps((float)(bins - 1u)));
    _mm_storeu_si128((__m128i *)(void *)k, _mm_cvttps_epi32(f));
#else
    int a;
    for (a = 0; a < 3; ++a) k[a] = kdrt__level_bin(c[a], lo[a], scale[a], bins);
#endif
}

static kdrt__box4 kdrt__box4_empty(void)
{
    kdrt__box4 box;
    int a;
    for (a = 0; a < 4; ++a) box.min[a] = INFINITY, box.max[a] = -INFINITY;
    return box;
}

/* box grown to hold b: the same min and max a lane on SSE2 and in plain C. */
static KDRT__FORCEINLINE void kdrt__grow_box(kdrt__box4 *box, const kdrt__box4 *b)
{
#if KDRT__SSE2
    _mm_storeu_ps(box->min, _mm_min_ps(_mm_loadu_ps(b->min), _mm_loadu_ps(box->min)));
    _mm_storeu_ps(box->max, _mm_max_ps(_mm_loadu_ps(b->max), _mm_loadu_ps(box->max)));
#else
    int a;
    for (a = 0; a < 4; ++a) {
        box->min[a] = b->min[a] < box->min[a] ? b->min[a] : box->min[a];
        box->max[a] = b->max[a] > box->max[a] ? b->max[a] : box->max[a];
    }
#endif
}

/* box grown to hold the point p (its 4 lanes), as kdrt__grow_box. */
static KDRT__FORCEINLINE void kdrt__grow_point(kdrt__box4 *box, const float p[4])
{
#if KDRT__SSE2
    const __m128 v = _mm_loadu_ps(p);
    _mm_storeu_ps(box->min, _mm_min_ps(v, _mm_loadu_ps(box->min)));
    _mm_storeu_ps(box->max, _mm_max_ps(v, _mm_loadu_ps(box->max)));
#else
    int a;
    for (a = 0; a < 4; ++a) {
        box->min[a] = p[a] < box->min[a] ? p[a] : box->min[a];
        box->max[a] = p[a] > box->max[a] ? p[a] : box->max[a];
    }
#endif
}

static kdrt_aabb kdrt__box3(const kdrt__box4 *b)
{
    kdrt_aabb box;
    memcpy(box.min, b->min, sizeof box.min), memcpy(box.max, b->max, sizeof box.max);
    return box;
}

/* Splits items[begin, end) (n > 1) by the binned SAH over their centres, as many bins as items
   up to KDRT__LEVEL_BINS, the three axes binned in one pass: 1 with *mid and the children's
   boxes, 0 for a leaf. */
static int kdrt__level_split(const kdrt__level_builder *b, const kdrt_aabb *box, uint32_t begin,
                             uint32_t end, uint32_t *mid, kdrt_aabb *left, kdrt_aabb *right)
{
    const uint32_t n = end - begin, bins = n < KDRT__LEVEL_BINS ? n : KDRT__LEVEL_BINS;
    /* Costs relative to the node's: a split costs KDRT__LEVEL_TRAVERSAL_COST * area more. */
    const double area = kdrt__half_area(box->min, box->max);
    double best = n > KDRT__LEVEL_MAX_LEAF ? INFINITY /* any split beats a leaf this big */
                                           : (KDRT__LEVEL_INSTANCE_COST * n - KDRT__LEVEL_TRAVERSAL_COST) * area;
    kdrt__box4 bin_box[3][KDRT__LEVEL_BINS], acc, below = kdrt__box4_empty(), above;
    kdrt__box4 centres = kdrt__box4_empty();
    uint32_t bin_count[3][KDRT__LEVEL_BINS], i, k, bin[4], best_axis = 3, best_bin = 0;
    float lo[4] = {0.0f, 0.0f, 0.0f, 0.0f}, scale[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    int axis;
    for (i = begin; i < end; ++i) kdrt__grow_point(&centres, b->prims[b->items[i]].centre);
    for (axis = 0; axis < 3; ++axis) {
        /* In double, so that a finite extent gives a finite scale (at most the largest float,
           for the tiniest extents); 0 for a flat axis, whose centres all fall in bin 0. */
        const double extent = (double)centres.max[axis] - centres.min[axis];
        const double per_unit = extent > 0.0 ? bins / extent : 0.0;
        lo[axis] = centres.min[axis];
        scale[axis] = per_unit < (double)FLT_MAX ? (float)per_unit : FLT_MAX;
        for (k = 0; k < bins; ++k) bin_box[axis][k] = kdrt__box4_empty(), bin_count[axis][k] = 0;
    }
    for (i = begin; i < end; ++i) {
        const kdrt__level_prim *p = &b->prims[b->items[i]];
        kdrt__level_bins(p->centre, lo, scale, bins, bin);
        for (axis = 0; axis < 3; ++axis) {
            bin_count[axis][bin[axis]] += 1u;
            kdrt__grow_box(&bin_box[axis][bin[axis]], &p->box);
        }
    }
    for (axis = 0; axis < 3; ++axis) {
        uint32_t above_count[KDRT__LEVEL_BINS], count = 0;
        double above_area[KDRT__LEVEL_BINS];
        if (scale[axis] == 0.0f) continue;
        acc = kdrt__box4_empty();
        /* Above the plane after bin k - 1: bins k and up, swept from the top. */
        for (k = bins - 1u; k > 0; --k) {
            if (bin_count[axis][k]) { /* an empty bin changes nothing above it */
                kdrt__grow_box(&acc, &bin_box[axis][k]), count += bin_count[axis][k];
                above_area[k] = kdrt__half_area(acc.min, acc.max);
            } else {
                above_area[k] = k + 1u < bins ? above_area[k + 1u] : 0.0;
            }
            above_count[k] = count;
        }
        acc = kdrt__box4_empty(), count = 0;
        for (k = 1; k < bins; ++k) {
            double cost;
            /* After an empty bin the plane costs what the one before it did. */
            if (!bin_count[axis][k - 1]) continue;
            kdrt__grow_box(&acc, &bin_box[axis][k - 1]), count += bin_count[axis][k - 1];
            if (above_count[k] == 0) continue;
            cost = KDRT__LEVEL_INSTANCE_COST * (kdrt__half_area(acc.min, acc.max) * count +
                                                above_area[k] * above_count[k]);
            if (cost < best) best = cost, best_axis = (uint32_t)axis, best_bin = k, below = acc;
        }
    }
    if (best_axis == 3) {
        uint32_t half;
        if (n <= KDRT__LEVEL_MAX_LEAF) return 0;
        /* Every centre at one point: halves in the items' order. */
        half = begin + n / 2u;
        above = kdrt__box4_empty();
        for (i = begin; i < end; ++i) kdrt__grow_box(i < half ? &below : &above, &b->prims[b->items[i]].box);
        *mid = half, *left = kdrt__box3(&below), *right = kdrt__box3(&above);
        return 1;
    }
    /* The bins below best_bin first, in place; the box of those above as they go. */
    above = kdrt__box4_empty();
    i = begin, k = end;
    while (i < k) {
        const uint32_t item = b->items[i];
        const kdrt__level_prim *p = &b->prims[item];
        if (kdrt__level_bin(p->centre[best_axis], lo[best_axis], scale[best_axis], bins) < best_bin) {
            ++i;
        } else {
            kdrt__grow_box(&above, &p->box);
            b->items[i] = b->items[--k];
            b->items[k] = item;
        }
    }
    *mid = i, *left = kdrt__box3(&below), *right = kdrt__box3(&above);
    return 1;
}

/* Node `node` over items[begin, end) in box: its lanes the (up to) 4 groups that splitting them
   by the SAH makes, the largest opened first, each a leaf or an inner node. The inner ones go to
   nodes[children] on, in lane order, each one's descendants after them: a subtree of m > 1
   instances has at most m - 1 nodes, so each subtree's place follows from its size alone, on
   any thread. */
static void kdrt__level_subtree(kdrt__level_builder *b, uint32_t node, uint32_t begin,
                                uint32_t end, const kdrt_aabb *box, uint32_t children,
                                uint32_t depth)
{
    struct {
        uint32_t begin, end;
        kdrt_aabb box;
        int open; /* the SAH may still split it */
    } g[4];
    kdrt__level_node *nd = &b->nodes[node];
    const int nodes_below = depth + 1u < KDRT__LEVEL_MAX_DEPTH;
    uint32_t count = 1, c, a, mid, inner = 0;
    if (b->tasks && end - begin <= b->task_size && b->task_count < KDRT__LEVEL_TASKS) {
        kdrt__level_task *t = &b->tasks[b->task_count++];
        t->node = node, t->begin = begin, t->end = end, t->children = children, t->depth = depth;
        t->box = *box;
        return;
    }
    g[0].begin = begin, g[0].end = end, g[0].box = *box, g[0].open = end - begin > 1u;
    while (count < 4u) {
        double largest = -1.0;
        uint32_t pick = 4u;
        for (c = 0; c < count; ++c) {
            const double area = kdrt__half_area(g[c].box.min, g[c].box.max);
            if (g[c].open && area > largest) largest = area, pick = c;
        }
        if (pick == 4u) break;
        if (!kdrt__level_split(b, &g[pick].box, g[pick].begin, g[pick].end, &mid, &g[pick].box,
                               &g[count].box)) {
            g[pick].open = 0;
            continue;
        }
        g[count].begin = mid, g[count].end = g[pick].end, g[pick].end = mid;
        g[count].open = g[count].end - mid > 1u, g[pick].open = mid - g[pick].begin > 1u;
        ++count;
    }
    for (c = 0; c < 4u; ++c) {
        const kdrt_aabb *lane = &g[c < count ? c : 0].box;
        for (a = 0; a < 3u; ++a) nd->lo[a][c] = lane->min[a], nd->hi[a][c] = lane->max[a];
        if (c >= count) {
            nd->first[c] = 0, nd->count[c] = KDRT_INVALID_ID;
        } else if (g[c].open && nodes_below) {
            nd->first[c] = children + inner++, nd->count[c] = 0;
        } else {
            nd->first[c] = g[c].begin, nd->count[c] = g[c].end - g[c].begin;
        }
    }
    /* The inner lanes' descendants after their nodes: at most m - 2 for m instances. */
    children += inner;
    for (c = 0; c < count; ++c)
        if (nd->count[c] == 0) {
            kdrt__level_subtree(b, nd->first[c], g[c].begin, g[c].end, &g[c].box, children,
                                depth + 1u);
            children += g[c].end - g[c].begin - 2u;
        }
}

static void kdrt__level_task_run(void *data, uint32_t index)
{
    kdrt__level_builder b = *(const kdrt__level_builder *)data;
    const kdrt__level_task t = b.tasks[index];
    b.tasks = NULL;
    kdrt__level_subtree(&b, t.node, t.begin, t.end, &t.box, t.children, t.depth);
}

/* The arena for n instances: a new one to swap in (*fresh), or NULL in *fresh when the current
   one fits. */
static kdrt_result kdrt__level_reserve(const kdrt_scene *sc, uint32_t n, void **fresh, size_t *bytes)
{
    size_t nodes, need;
    *fresh = NULL;
    if (!kdrt__mul_size(n, sizeof(kdrt__level_node), &nodes) ||
        !kdrt__mul_size(n, sizeof(kdrt__level_prim) + sizeof(uint32_t), &need) ||
        need > (size_t)-1 - nodes)
        return KDRT_ERROR_SIZE_OVERFLOW;
    *bytes = need + nodes;
    if (*bytes <= sc->top.arena_bytes) return KDRT_SUCCESS;
    *fresh = kdrt__alloc(&sc->options.allocator, *bytes);
    return *fresh ? KDRT_SUCCESS : KDRT_ERROR_OUT_OF_MEMORY;
}

/* Builds the top level over the instances in the arena (reserved for their count): those that
   no query can see (an empty box, mask 0 or disabled) are left out. Cannot fail. */
static void kdrt__level_build(kdrt_scene *sc)
{
    const uint32_t n = sc->now.instance_count;
    const kdrt__instance *in = sc->now.instances;
    kdrt__level *top = &sc->top;
    kdrt__level_task tasks[KDRT__LEVEL_TASKS];
    kdrt__level_builder b;
    kdrt_aabb seen = kdrt_aabb_empty(); /* the boxes a query may see */
    uint32_t i, count = 0;
    top->bounds = kdrt_aabb_empty();
    top->nodes = NULL;
    if (n == 0) return;
    top->nodes = (kdrt__level_node *)top->arena;
    top->prims = (kdrt__level_prim *)(top->nodes + n); /* at most n - 1 nodes, and 1 */
    top->items = (uint32_t *)(top->prims + n);
    for (i = 0; i < n; ++i) {
        kdrt__level_prim *p = &top->prims[i];
        int a;
        for (a = 0; a < 3; ++a) {
            p->box.min[a] = in[i].box.min[a], p->box.max[a] = in[i].box.max[a];
            p->centre[a] = 0.5f * in[i].box.min[a] + 0.5f * in[i].box.max[a];
        }
        p->box.min[3] = p->box.max[3] = p->centre[3] = 0.0f;
        top->bounds = kdrt_aabb_union(top->bounds, in[i].box); /* the scene's box holds them all */
        if (in[i].mask && in[i].box.min[0] <= in[i].box.max[0]) {
            top->items[count++] = i;
            seen = kdrt_aabb_union(seen, in[i].box);
        }
    }
    if (count == 0) {
        top->nodes = NULL;
        return;
    }
    b.nodes = top->nodes, b.items = top->items, b.prims = top->prims;
    b.tasks = NULL, b.task_count = 0, b.task_size = 0;
    if (count >= KDRT__LEVEL_PARALLEL_MIN && sc->options.scheduler.run)
        b.tasks = tasks, b.task_size = count / 16u;
    top->root = seen;
    kdrt__level_subtree(&b, 0, 0, count, &seen, 1, 0);
    if (b.task_count)
        sc->options.scheduler.run(sc->options.scheduler.user, kdrt__level_task_run, &b, b.task_count);
}

/* ---- the entries: finding, laying out, committing ---- */

static int kdrt__geometry_order(const void *a, const void *b)
{
    const uint32_t x = ((const kdrt_geometry *)a)->id, y = ((const kdrt_geometry *)b)->id;
    return (x > y) - (x < y);
}

/* The first of the count entries (sorted by ID) whose ID is not below id. */
static uint32_t kdrt__entry_index(const kdrt_geometry *entries, uint32_t count, uint32_t id)
{
    uint32_t lo = 0, hi = count;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2u;
        if (entries[mid].id < id) lo = mid + 1u;
        else hi = mid;
    }
    return lo;
}

/* The committed entry with this ID, or NULL. */
static const kdrt_geometry *kdrt__find_entry(const kdrt_scene *scene, uint32_t id)
{
    const uint32_t i = kdrt__entry_index(scene->now.entries, scene->now.entry_count, id);
    return i < scene->now.entry_count && scene->now.entries[i].id == id ? &scene->now.entries[i]
                                                                        : NULL;
}

/* The entry with this ID from the next commit on, or NULL. */
static kdrt_geometry *kdrt__find_next(kdrt_scene *scene, uint32_t id)
{
    const uint32_t i = kdrt__entry_index(scene->next, scene->next_count, id);
    return i < scene->next_count && scene->next[i].id == id ? &scene->next[i] : NULL;
}

/* The committed instance with this ID, or NULL. */
static const kdrt__instance *kdrt__find_instance(const kdrt_scene *scene, uint32_t id)
{
    const kdrt_geometry *e = kdrt__find_entry(scene, id);
    if (!e || e->type != KDRT_GEOMETRY_INSTANCE) return NULL;
    return &scene->now.instances[scene->now.slot[e - scene->now.entries]];
}

static void kdrt__layout_free(const kdrt_allocator *a, kdrt__layout *l)
{
    kdrt__free(a, l->entries);
    kdrt__free(a, l->slot);
    kdrt__free(a, l->parts);
    kdrt__free(a, l->instances);
    memset(l, 0, sizeof *l);
}

KDRT_API void kdrt_scene_free(kdrt_scene *scene)
{
    kdrt_allocator a;
    if (!scene) return;
    a = scene->options.allocator;
    kdrt_tree_free(scene->meshes);
    kdrt__layout_free(&a, &scene->now);
    kdrt__free(&a, scene->top.arena);
    kdrt__free(&a, scene->next);
    kdrt__free(&a, scene);
}

/* A query sees a geometry through this mask: 0 when it is disabled. */
static uint32_t kdrt__entry_mask(const kdrt_geometry *e)
{
    return (e->flags & KDRT_GEOMETRY_DISABLED) ? 0u : e->mask;
}

/* One entry checked as kdrt_scene_build() and kdrt_scene_attach() take it, the instance placed
   in *in (when it is one and in is not NULL). */
static kdrt_result kdrt__check_entry(const kdrt_geometry *e, kdrt_triangles *view,
                                     kdrt__instance *in)
{
    kdrt__instance scratch;
    if (e->id == KDRT_INVALID_ID) return KDRT_ERROR_INVALID_GEOMETRY_ID;
    if (e->flags & ~(uint32_t)KDRT_GEOMETRY_DISABLED) return KDRT_ERROR_INVALID_OPTION;
    if (e->type == KDRT_GEOMETRY_MESH) return kdrt__check_view(&e->mesh, view);
    if (e->type != KDRT_GEOMETRY_INSTANCE) return KDRT_ERROR_INVALID_OPTION;
    if (!e->tree) return KDRT_ERROR_NULL_ARGUMENT;
    return kdrt__place_instance(e->tree, e->transform, in ? in : &scratch);
}

/* The layout of the entries to come (next): each checked, report naming the one at fault; an
   instance whose tree and transform are as committed keeps its placing. */
static kdrt_result kdrt__lay_out(const kdrt_scene *sc, kdrt__layout *l, kdrt_build_report *report)
{
    const kdrt_allocator *a = &sc->options.allocator;
    uint32_t i, old = 0, meshes = 0, triangles = 0;
    memset(l, 0, sizeof *l);
    for (i = 0; i < sc->next_count; ++i) meshes += sc->next[i].type == KDRT_GEOMETRY_MESH;
    l->entries = (kdrt_geometry *)kdrt__alloc(a, (size_t)sc->next_count * sizeof *l->entries);
    l->slot = (uint32_t *)kdrt__alloc(a, (size_t)sc->next_count * sizeof *l->slot);
    l->parts = (kdrt__part *)kdrt__alloc(a, (size_t)meshes * sizeof *l->parts);
    l->instances = (kdrt__instance *)kdrt__alloc(a, (size_t)(sc->next_count - meshes) *
                                                        sizeof *l->instances);
    if (!l->entries || !l->slot || !l->parts || !l->instances) {
        kdrt__layout_free(a, l);
        return KDRT_ERROR_OUT_OF_MEMORY;
    }
    if (sc->next_count) memcpy(l->entries, sc->next, (size_t)sc->next_count * sizeof *l->entries);
    l->entry_count = sc->next_count;
    for (i = 0; i < l->entry_count; ++i) {
        const kdrt_geometry *e = &l->entries[i];
        kdrt_result r = KDRT_SUCCESS;
        if (report) report->invalid_geometry = e->id;
        if (i > 0 && e->id == l->entries[i - 1].id) r = KDRT_ERROR_INVALID_GEOMETRY_ID;
        else if (e->type == KDRT_GEOMETRY_MESH) {
            kdrt__part *part = &l->parts[l->part_count];
            r = kdrt__check_entry(e, &part->mesh, NULL);
            if (r == KDRT_SUCCESS && part->mesh.triangle_count > KDRT_MAX_TRIANGLES - triangles)
                r = KDRT_ERROR_SIZE_OVERFLOW;
            part->first = triangles, part->id = e->id, part->mask = kdrt__entry_mask(e);
            triangles += part->mesh.triangle_count;
            l->slot[i] = l->part_count++;
        } else {
            kdrt__instance *in = &l->instances[l->instance_count];
            const kdrt__instance *was = sc->now.instances;
            while (old < sc->now.instance_count && was[old].id < e->id) ++old;
            if (e->type == KDRT_GEOMETRY_INSTANCE && old < sc->now.instance_count &&
                was[old].id == e->id && was[old].tree == e->tree &&
                memcmp(kdrt__find_entry(sc, e->id)->transform, e->transform,
                       sizeof e->transform) == 0)
                *in = was[old]; /* placed as committed: the checks passed then */
            else r = kdrt__check_entry(e, NULL, in);
            in->id = e->id, in->mask = kdrt__entry_mask(e);
            l->slot[i] = l->instance_count++;
        }
        if (r != KDRT_SUCCESS) {
            kdrt__layout_free(a, l);
            return r;
        }
    }
    if (report) report->invalid_geometry = KDRT_INVALID_ID;
    return KDRT_SUCCESS;
}

/* A new tree over the layout's meshes (NULL: none), report naming a bad triangle's mesh. */
static kdrt_result kdrt__build_meshes(const kdrt_scene *sc, const kdrt__layout *l,
                                      kdrt_tree **out, kdrt_build_report *report)
{
    kdrt__meshes m;
    kdrt_result r;
    *out = NULL;
    m.parts = l->parts, m.count = l->part_count;
    m.triangles = m.count ? l->parts[m.count - 1].first + l->parts[m.count - 1].mesh.triangle_count
                          : 0u;
    if (sc->load) {
        /* The file's meshes must be these, in ID order: the first that differs is named. */
        uint32_t bad;
        r = kdrt__check_meshes(sc->load, &m, &bad);
        if (r != KDRT_SUCCESS) {
            if (report) report->invalid_geometry = bad < m.count ? m.parts[bad].id : KDRT_INVALID_ID;
            return r;
        }
    }
    if (l->part_count == 0) return KDRT_SUCCESS;
    *out = kdrt__tree_new(&sc->options, &m);
    if (!*out) return KDRT_ERROR_OUT_OF_MEMORY;
    if (sc->load)
        r = kdrt__load_tree(*out, sc->load, sc->options.flags); /* frees it on failure */
    else
        r = kdrt__build_tree(*out, &sc->options, report); /* frees it on failure */
    if (r != KDRT_SUCCESS) *out = NULL;
    if (report && report->invalid_triangle != KDRT_INVALID_ID) {
        /* The tree numbers triangles across the meshes: name the mesh and its own, for a
           failure or the first triangle skipped. */
        const kdrt__part *part = kdrt__part_of(&m, report->invalid_triangle);
        report->invalid_triangle -= part->first;
        report->invalid_geometry = part->id;
    }
    return r;
}

/* Entries [begin, end) of a commit that keeps the same IDs in the same places: each taken from
   next, an instance placed again when its tree or transform changed, masks as the flags say. */
static void kdrt__update_entries(kdrt_scene *sc, uint32_t begin, uint32_t end)
{
    uint32_t i;
    for (i = begin; i < end; ++i) {
        kdrt_geometry *e = &sc->now.entries[i];
        const kdrt_geometry *next = &sc->next[i];
        if (e->type == KDRT_GEOMETRY_INSTANCE) {
            kdrt__instance *in = &sc->now.instances[sc->now.slot[i]];
            if (e->tree != next->tree ||
                memcmp(e->transform, next->transform, sizeof e->transform) != 0) {
                const kdrt_result r = kdrt__place_instance(next->tree, next->transform, in);
                KDRT_ASSERT(r == KDRT_SUCCESS); /* checked when attached or moved */
                (void)r;
            }
            in->mask = kdrt__entry_mask(next);
        } else {
            sc->now.parts[sc->now.slot[i]].mask = kdrt__entry_mask(next);
        }
        *e = *next;
    }
}

static void kdrt__update_task(void *data, uint32_t chunk)
{
    kdrt_scene *sc = (kdrt_scene *)data;
    kdrt__update_entries(sc, kdrt__chunk_start(sc->now.entry_count, chunk),
                         kdrt__chunk_start(sc->now.entry_count, chunk + 1u));
}

/* Whether the next commit keeps every ID in its place (no entry added or removed for good). */
static int kdrt__same_ids(const kdrt_scene *sc)
{
    uint32_t i;
    if (sc->next_count != sc->now.entry_count) return 0;
    for (i = 0; i < sc->next_count; ++i)
        if (sc->next[i].id != sc->now.entries[i].id) return 0;
    return 1;
}

/* The commit: the entries laid out anew when IDs came or went (the mesh tree rebuilt when
   meshes did), else updated in place (a detached and attached ID, a tree swapped under an
   instance, a move, a flag); then the top level. Everything that can fail comes first, so that a
   failure leaves the scene as it was. */
static kdrt_result kdrt__commit(kdrt_scene *sc, kdrt_build_report *report)
{
    const kdrt_allocator *a = &sc->options.allocator;
    int relayout;
    kdrt__layout l;
    kdrt_tree *meshes = NULL;
    void *arena;
    size_t bytes;
    uint32_t i;
    kdrt_result r;
    memset(&l, 0, sizeof l);
    if (!sc->entries_changed && !sc->moved) return KDRT_SUCCESS; /* nothing to do */
    relayout = sc->meshes_changed || (sc->entries_changed && !kdrt__same_ids(sc));
    if (relayout) {
        r = kdrt__lay_out(sc, &l, report);
        if (r == KDRT_SUCCESS && sc->meshes_changed) r = kdrt__build_meshes(sc, &l, &meshes, report);
        if (r != KDRT_SUCCESS) {
            kdrt__layout_free(a, &l);
            return r;
        }
    }
    r = kdrt__level_reserve(sc, relayout ? l.instance_count : sc->now.instance_count, &arena,
                            &bytes);
    if (r != KDRT_SUCCESS) {
        kdrt_tree_free(meshes);
        kdrt__layout_free(a, &l);
        return r;
    }
    /* Nothing fails from here on. */
    if (arena) {
        kdrt__free(a, sc->top.arena);
        sc->top.arena = arena, sc->top.arena_bytes = bytes;
    }
    if (relayout) {
        kdrt__layout_free(a, &sc->now);
        sc->now = l;
        if (sc->meshes_changed) {
            kdrt_tree_free(sc->meshes);
            sc->meshes = meshes;
        }
    } else if (sc->now.instance_count >= KDRT__LEVEL_PARALLEL_MIN && sc->options.scheduler.run) {
        sc->options.scheduler.run(sc->options.scheduler.user, kdrt__update_task, sc, KDRT__CHUNKS);
    } else {
        kdrt__update_entries(sc, 0, sc->now.entry_count);
    }
    if (sc->meshes && !sc->meshes_changed) {
        /* The same meshes in the same order: only their masks may have changed. */
        sc->meshes->meshes.parts = sc->now.parts;
        sc->meshes->masks_full = 1;
        for (i = 0; i < sc->now.part_count; ++i)
            sc->meshes->masks_full &= sc->now.parts[i].mask == 0xFFFFFFFFu;
    }
    kdrt__level_build(sc);
    sc->bounds = kdrt_aabb_union(sc->meshes ? sc->meshes->bounds : kdrt_aabb_empty(),
                                 sc->top.bounds);
    sc->entries_changed = sc->meshes_changed = sc->moved = 0;
    return KDRT_SUCCESS;
}

/* Room in next for one more entry. */
static kdrt_result kdrt__next_reserve(kdrt_scene *sc)
{
    if (sc->next_count == KDRT_INVALID_ID) return KDRT_ERROR_SIZE_OVERFLOW;
    return kdrt__reserve(&sc->options.allocator, (void **)&sc->next, &sc->next_capacity,
                         sc->next_count + 1u, sizeof *sc->next);
}

/* kdrt_scene_build(), and kdrt_scene_load() when file is not NULL (the mesh tree loaded from
   it), with checked options. */
static kdrt_result kdrt__scene_make(const kdrt_geometry *geometries, uint32_t count,
                                    const kdrt__file *file, const kdrt_build_options *options,
                                    kdrt_scene **out_scene, kdrt_build_report *report)
{
    const kdrt_build_options opt = *options;
    kdrt_scene *sc;
    kdrt_result r;
    sc = (kdrt_scene *)kdrt__alloc(&opt.allocator, sizeof *sc);
    if (!sc) return KDRT_ERROR_OUT_OF_MEMORY;
    memset(sc, 0, sizeof *sc);
    sc->options = opt;
    sc->load = file;
    sc->top.bounds = sc->bounds = kdrt_aabb_empty();
    /* The scene is its first commit: every entry to come, then laid out and built. */
    r = kdrt__reserve(&opt.allocator, (void **)&sc->next, &sc->next_capacity, count,
                      sizeof *sc->next);
    if (r == KDRT_SUCCESS) {
        if (count) memcpy(sc->next, geometries, (size_t)count * sizeof *sc->next);
        sc->next_count = count;
        /* In ID order, so that the mesh tree's triangle numbers order hits as the tie rule does. */
        if (count > 1) qsort(sc->next, count, sizeof *sc->next, kdrt__geometry_order);
        sc->entries_changed = sc->meshes_changed = 1;
        r = kdrt__commit(sc, report);
    }
    sc->load = NULL; /* later commits build */
    if (r != KDRT_SUCCESS) {
        kdrt_scene_free(sc);
        return r;
    }
    *out_scene = sc;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_scene_build(const kdrt_geometry *geometries, uint32_t count,
                                      const kdrt_build_options *options, kdrt_scene **out_scene,
                                      kdrt_build_report *report)
{
    kdrt_build_options opt = options ? *options : kdrt_default_build_options();
    kdrt_result r;
    kdrt__report_init(report);
    if (!out_scene) return KDRT_ERROR_NULL_ARGUMENT;
    *out_scene = NULL;
    if (!geometries && count) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__check_options(&opt);
    if (r != KDRT_SUCCESS) return r;
    return kdrt__scene_make(geometries, count, NULL, &opt, out_scene, report);
}

KDRT_API kdrt_result kdrt_scene_load(const kdrt_geometry *geometries, uint32_t count,
                                     const void *bytes, size_t size,
                                     const kdrt_build_options *options, kdrt_scene **out_scene,
                                     kdrt_build_report *report)
{
    kdrt_build_options opt = options ? *options : kdrt_default_build_options();
    kdrt__file f;
    kdrt_result r;
    kdrt__report_init(report);
    if (!out_scene) return KDRT_ERROR_NULL_ARGUMENT;
    *out_scene = NULL;
    if (!geometries && count) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__check_load_options(&opt);
    if (r == KDRT_SUCCESS) r = kdrt__read_header(bytes, size, &f);
    if (r != KDRT_SUCCESS) return r;
    /* The file's shape, so that a commit that rebuilds the mesh tree makes one of its kind; the
       caller's allocator, scheduler and kernel flags. */
    opt.builder = f.options.builder, opt.quality = f.options.quality;
    opt.intersector = f.options.intersector, opt.max_leaf_size = f.options.max_leaf_size;
    opt.max_depth = f.options.max_depth;
    opt.sah_traversal_cost = f.options.sah_traversal_cost;
    opt.sah_intersection_cost = f.options.sah_intersection_cost;
    opt.sah_empty_bonus = f.options.sah_empty_bonus;
    opt.flags = (opt.flags & ~(uint32_t)KDRT_BUILD_SKIP_INVALID_TRIANGLES) | f.options.flags;
    return kdrt__scene_make(geometries, count, &f, &opt, out_scene, report);
}

KDRT_API size_t kdrt_scene_saved_size(const kdrt_scene *scene)
{
    uint64_t count[KDRT__SECTIONS];
    if (!scene) return 0;
    kdrt__section_counts(scene->meshes, count);
    return (size_t)kdrt__saved_bytes(count);
}

KDRT_API kdrt_result kdrt_scene_save_meshes(const kdrt_scene *scene, kdrt_write_fn write,
                                            void *user)
{
    kdrt_build_options shape;
    if (!scene) return KDRT_ERROR_NULL_ARGUMENT;
    if (scene->meshes) return kdrt__save(scene->meshes, &scene->meshes->shape,
                                         scene->meshes->depth_limit, write, user);
    shape = scene->options;
    shape.flags &= (uint32_t)KDRT_BUILD_SKIP_INVALID_TRIANGLES;
    return kdrt__save(NULL, &shape, shape.max_depth ? (shape.max_depth < KDRT_MAX_DEPTH
                                                           ? shape.max_depth : KDRT_MAX_DEPTH)
                                                    : kdrt__default_depth(0),
                      write, user);
}

KDRT_API kdrt_result kdrt_scene_commit(kdrt_scene *scene)
{
    if (!scene) return KDRT_ERROR_NULL_ARGUMENT;
    return kdrt__commit(scene, NULL);
}

KDRT_API kdrt_result kdrt_scene_set_transform(kdrt_scene *scene, uint32_t id,
                                              const float transform[12])
{
    kdrt_geometry *e;
    kdrt__instance check;
    kdrt_result r;
    if (!scene || !transform) return KDRT_ERROR_NULL_ARGUMENT;
    e = kdrt__find_next(scene, id);
    if (!e || e->type != KDRT_GEOMETRY_INSTANCE) return KDRT_ERROR_INVALID_GEOMETRY_ID;
    r = kdrt__place_instance(e->tree, transform, &check);
    if (r != KDRT_SUCCESS) return r;
    memcpy(e->transform, transform, sizeof e->transform);
    scene->moved = 1;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_scene_attach(kdrt_scene *scene, const kdrt_geometry *geometry)
{
    kdrt_triangles view;
    uint32_t at;
    kdrt_result r;
    if (!scene || !geometry) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__check_entry(geometry, &view, NULL);
    if (r != KDRT_SUCCESS) return r;
    at = kdrt__entry_index(scene->next, scene->next_count, geometry->id);
    if (at < scene->next_count && scene->next[at].id == geometry->id)
        return KDRT_ERROR_INVALID_GEOMETRY_ID;
    r = kdrt__next_reserve(scene);
    if (r != KDRT_SUCCESS) return r;
    memmove(&scene->next[at + 1u], &scene->next[at],
            (size_t)(scene->next_count - at) * sizeof *scene->next);
    scene->next[at] = *geometry;
    scene->next_count += 1u;
    scene->entries_changed = 1;
    scene->meshes_changed |= geometry->type == KDRT_GEOMETRY_MESH;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_scene_detach(kdrt_scene *scene, uint32_t id)
{
    kdrt_geometry *e;
    uint32_t at;
    if (!scene) return KDRT_ERROR_NULL_ARGUMENT;
    e = kdrt__find_next(scene, id);
    if (!e) return KDRT_ERROR_INVALID_GEOMETRY_ID;
    at = (uint32_t)(e - scene->next);
    scene->entries_changed = 1;
    scene->meshes_changed |= e->type == KDRT_GEOMETRY_MESH;
    memmove(e, e + 1, (size_t)(scene->next_count - at - 1u) * sizeof *e);
    scene->next_count -= 1u;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_scene_enable(kdrt_scene *scene, uint32_t id, int enabled)
{
    kdrt_geometry *e;
    if (!scene) return KDRT_ERROR_NULL_ARGUMENT;
    e = kdrt__find_next(scene, id);
    if (!e) return KDRT_ERROR_INVALID_GEOMETRY_ID;
    if (enabled) e->flags &= ~(uint32_t)KDRT_GEOMETRY_DISABLED;
    else e->flags |= (uint32_t)KDRT_GEOMETRY_DISABLED;
    scene->entries_changed = 1;
    return KDRT_SUCCESS;
}

KDRT_API const kdrt_geometry *kdrt_scene_geometry(const kdrt_scene *scene, uint32_t id)
{
    return scene ? kdrt__find_entry(scene, id) : NULL;
}

KDRT_API kdrt_aabb kdrt_scene_bounds(const kdrt_scene *scene)
{
    return scene ? scene->bounds : kdrt_aabb_empty();
}

/* ---- queries ---- */

/* The world ray in the instance's space, evaluated in double and rounded once; its range is
   tmin to tmax (t is the same parameter in both spaces: dir is not renormalised). */
static void kdrt__object_ray(const kdrt__instance *in, const kdrt_ray *ray, float tmax,
                             kdrt_ray *out)
{
    double o[3];
    int i;
    for (i = 0; i < 3; ++i) o[i] = (double)ray->org[i] - in->to_world[4 * i + 3];
    for (i = 0; i < 3; ++i) {
        const double *row = &in->to_object[3 * i];
        out->org[i] = (float)(row[0] * o[0] + row[1] * o[1] + row[2] * o[2]);
        out->dir[i] = (float)(row[0] * ray->dir[0] + row[1] * ray->dir[1] + row[2] * ray->dir[2]);
    }
    out->tmin = ray->tmin;
    out->tmax = tmax;
    out->cell = 0; /* the world ray's cell is the mesh tree's: the instance's walk starts at its root */
}

/* A nearest hit of the scene's mesh tree (a tree-wide triangle number) named as the caller
   knows it: the mesh's geometry ID and its own triangle index. */
static void kdrt__name_mesh_hit(const kdrt_tree *meshes, kdrt_hit *hit)
{
    const kdrt__part *part = kdrt__part_of(&meshes->meshes, hit->triangle);
    hit->triangle -= part->first, hit->geometry = part->id;
}

/* The top level's slab test, kdrt__clip_to_box's conservative entry and exit, for rays whose
   inverse direction is finite on every axis (no axis needs the origin alone): no branch an
   axis. */
/* The slab test of a node's four lanes: kdrt__clip_to_box's conservative entry and exit, for
   rays whose inverse direction is finite on every axis (no axis needs the origin alone). A bit
   a lane met, its entry in near[]; on SSE2 the same arithmetic 4 lanes at a time. */
static KDRT__FORCEINLINE unsigned kdrt__level_clip4(const kdrt__level_node *n,
                                                    const kdrt__ray_setup *s, float near[4])
{
#if KDRT__SSE2
    __m128 enter = _mm_set1_ps(s->tmin), exit = _mm_set1_ps(s->tmax);
    const __m128 down = _mm_set1_ps(1.0f - KDRT__T_SLACK), up = _mm_set1_ps(1.0f + KDRT__T_SLACK);
    int a;
    for (a = 0; a < 3; ++a) {
        const __m128 o = _mm_set1_ps(s->org[a]), inv = _mm_set1_ps(s->inv_dir[a]);
        const __m128 ta = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(n->lo[a]), o), inv);
        const __m128 tb = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(n->hi[a]), o), inv);
        /* As the scalar test's ternaries: the running entry and exit second, kept on a tie. */
        enter = _mm_max_ps(_mm_mul_ps(_mm_min_ps(ta, tb), down), enter);
        exit = _mm_min_ps(_mm_mul_ps(_mm_max_ps(ta, tb), up), exit);
    }
    _mm_storeu_ps(near, enter);
    return (unsigned)_mm_movemask_ps(_mm_cmple_ps(enter, exit));
#else
    unsigned hits = 0, c;
    for (c = 0; c < 4u; ++c) {
        float enter = s->tmin, exit = s->tmax;
        int a;
        for (a = 0; a < 3; ++a) {
            const float ta = (n->lo[a][c] - s->org[a]) * s->inv_dir[a];
            const float tb = (n->hi[a][c] - s->org[a]) * s->inv_dir[a];
            const float tnear = (ta < tb ? ta : tb) * (1.0f - KDRT__T_SLACK);
            const float tfar = (ta < tb ? tb : ta) * (1.0f + KDRT__T_SLACK);
            enter = tnear > enter ? tnear : enter;
            exit = tfar < exit ? tfar : exit;
        }
        near[c] = enter;
        hits |= (unsigned)(enter <= exit) << c;
    }
    return hits;
#endif
}

/* The same for any ray, each lane through kdrt__clip_to_box. */
static unsigned kdrt__level_clip4_any(const kdrt__level_node *n, const kdrt__ray_setup *s,
                                      float near[4])
{
    unsigned hits = 0, c;
    for (c = 0; c < 4u; ++c) {
        kdrt_aabb box;
        float far;
        int a;
        for (a = 0; a < 3; ++a) box.min[a] = n->lo[a][c], box.max[a] = n->hi[a][c];
        hits |= (unsigned)kdrt__clip_to_box(&box, s, &near[c], &far) << c;
    }
    return hits;
}

/* One instance of the walk: skipped unless its mask lets the query through and (unless
   box_tested: a leaf of one, whose box is the instance's) the ray meets its world box before the
   best hit, else walked in its space. As kdrt__walk_instances, and 2 for an any-hit found. */
static int kdrt__walk_instance(const kdrt__instance *in, const kdrt_ray *ray,
                               const kdrt_query *query, kdrt__ray_setup *s, int box_tested,
                               kdrt_hit *best, int any_hit, kdrt__hit_list *list)
{
    kdrt__rules storage;
    const kdrt__rules *rules;
    kdrt_ray object;
    kdrt_hit h;
    float enter, exit;
    if (!(in->mask & (query ? query->mask : 0xFFFFFFFFu))) return 0;
    s->tmax = best->t;
    if (!box_tested && !kdrt__clip_to_box(&in->box, s, &enter, &exit)) return 0;
    rules = kdrt__rules_for(query, ray, in->tree, in->id, in->mirrored, list != NULL, &storage);
    kdrt__object_ray(in, ray, best->t, &object);
    if (!kdrt__walk(in->tree, &object, rules, &h, any_hit, list)) {
        best->t = kdrt__list_bound(list, best->t);
        return 0;
    }
    if (any_hit) return 2;
    h.geometry = h.instance = in->id, h.cell = 0;
    if (best->triangle != KDRT_INVALID_ID && !kdrt__hit_before(&h, best)) return 0;
    *best = h;
    return 1;
}

/* A lane waiting on the walk's stack: as kdrt__level_node's, with its entry. */
typedef struct kdrt__level_todo {
    uint32_t first, count;
    float t0;
} kdrt__level_todo;

/* The walk of the top level, nearer lanes first: each instance the ray's range reaches and its
   mask lets through is walked in its own space. Nearest hit: *best holds the hit so far (or a
   miss whose t is the range's end) and takes nearer ones; any_hit: 1 on the first; list: its
   hits go there. */
static int kdrt__walk_instances(const kdrt_scene *sc, const kdrt_ray *ray, const kdrt_query *query,
                                kdrt_hit *best, int any_hit, kdrt__hit_list *list)
{
    const kdrt__level_node *nodes = sc->top.nodes;
    kdrt__level_todo stack[KDRT__LEVEL_STACK];
    uint32_t sp = 0, node = 0, i;
    kdrt__ray_setup s;
    float t0, t1;
    int found = 0, finite;
    if (!nodes || !kdrt__setup_ray(ray, &s)) return 0;
    s.tmax = best->t;
    if (!kdrt__clip_to_box(&sc->top.root, &s, &t0, &t1)) return 0;
    finite = kdrt__finite(s.inv_dir[0]) && kdrt__finite(s.inv_dir[1]) && kdrt__finite(s.inv_dir[2]);
    for (;;) {
        const kdrt__level_node *n = &nodes[node];
        float near[4];
        unsigned hits, c;
        uint32_t pushed = sp;
        s.tmax = best->t;
        hits = finite ? kdrt__level_clip4(n, &s, near) : kdrt__level_clip4_any(n, &s, near);
        /* The lanes met, farthest first on the stack (an insertion sort of at most 4). */
        for (c = 0; c < 4u; ++c) {
            uint32_t at = sp++;
            if (!((hits >> c) & 1u) || n->count[c] == KDRT_INVALID_ID) {
                --sp;
                continue;
            }
            while (at > pushed && stack[at - 1u].t0 < near[c]) stack[at] = stack[at - 1u], --at;
            stack[at].first = n->first[c], stack[at].count = n->count[c], stack[at].t0 = near[c];
        }
        for (;;) {
            kdrt__level_todo e;
            if (sp == 0) return found;
            e = stack[--sp];
            if (e.t0 > best->t) continue;
            if (e.count == 0) {
                node = e.first;
                break;
            }
            for (i = 0; i < e.count; ++i) {
                const int r = kdrt__walk_instance(&sc->now.instances[sc->top.items[e.first + i]],
                                                  ray, query, &s, e.count == 1u, best, any_hit,
                                                  list);
                if (r == 2) return 1;
                found |= r;
            }
        }
    }
}

/* A scene query: the meshes' tree, then the instances. best as kdrt__walk_instances's. */
static int kdrt__scene_query(const kdrt_scene *sc, const kdrt_ray *ray, const kdrt_query *query,
                             kdrt_hit *best, int any_hit, kdrt__hit_list *list)
{
    int found = 0;
    kdrt__miss(best);
    best->t = ray->tmax;
    if (query && query->mask == 0) return 0;
    if (sc->meshes) {
        kdrt__rules storage;
        const kdrt__rules *rules =
            kdrt__rules_for(query, ray, sc->meshes, KDRT_INVALID_ID, 0, list != NULL, &storage);
        kdrt_hit h;
        if (kdrt__walk(sc->meshes, ray, rules, &h, any_hit, list)) {
            if (any_hit) return 1;
            kdrt__name_mesh_hit(sc->meshes, &h);
            *best = h, found = 1;
        } else {
            best->t = kdrt__list_bound(list, best->t);
        }
    }
    if (sc->top.nodes) found |= kdrt__walk_instances(sc, ray, query, best, any_hit, list);
    if (!found && !list) kdrt__miss(best);
    return found;
}

KDRT_API int kdrt_scene_intersect(const kdrt_scene *scene, const kdrt_ray *ray,
                                  const kdrt_query *query, kdrt_hit *hit)
{
    if (!hit) return 0;
    if (!scene || !ray) {
        kdrt__miss(hit);
        return 0;
    }
    if (scene->meshes && !scene->top.nodes && scene->meshes->masks_full &&
        (!query || (!query->flags && !query->filter && query->mask))) {
        /* Static meshes, every hit counting: the one tree's query, its hit named. */
        if (!kdrt_intersect(scene->meshes, ray, hit)) return 0;
        kdrt__name_mesh_hit(scene->meshes, hit);
        return 1;
    }
    return kdrt__scene_query(scene, ray, query, hit, 0, NULL);
}

KDRT_API int kdrt_scene_occluded(const kdrt_scene *scene, const kdrt_ray *ray,
                                 const kdrt_query *query)
{
    kdrt_hit hit;
    return scene && ray && kdrt__scene_query(scene, ray, query, &hit, 1, NULL);
}

/* A scene's batch: its mesh tree's rays in packets (kdrt__batch) when every hit of it counts, each
   ray then through the instances as kdrt__scene_query takes it there. */
KDRT_API uint32_t kdrt_scene_intersect_batch(const kdrt_scene *scene, const kdrt_ray *rays,
                                             uint32_t count, const kdrt_query *query,
                                             kdrt_hit *hits)
{
    uint32_t i, found = 0;
    if (!hits) return 0;
    if (scene && rays && scene->meshes && kdrt__query_is_plain(scene->meshes, query)) {
        kdrt__batch(scene->meshes, rays, count, hits, NULL, 0, NULL);
        for (i = 0; i < count; ++i) {
            kdrt_hit *best = &hits[i];
            int hit = best->triangle != KDRT_INVALID_ID;
            if (hit) kdrt__name_mesh_hit(scene->meshes, best);
            if (scene->top.nodes) {
                if (!hit) kdrt__miss(best), best->t = rays[i].tmax;
                hit |= kdrt__walk_instances(scene, &rays[i], query, best, 0, NULL);
                if (!hit) kdrt__miss(best);
            }
            found += (uint32_t)hit;
        }
        return found;
    }
    for (i = 0; i < count; ++i) {
        if (scene && rays) found += (uint32_t)kdrt_scene_intersect(scene, &rays[i], query, &hits[i]);
        else kdrt__miss(&hits[i]);
    }
    return found;
}

KDRT_API uint32_t kdrt_scene_occluded_batch(const kdrt_scene *scene, const kdrt_ray *rays,
                                            uint32_t count, const kdrt_query *query,
                                            uint8_t *occluded)
{
    uint32_t i, found = 0;
    if (!occluded) return 0;
    if (scene && rays && scene->meshes && kdrt__query_is_plain(scene->meshes, query)) {
        kdrt__batch(scene->meshes, rays, count, NULL, occluded, 1, NULL);
        for (i = 0; i < count; ++i) {
            if (!occluded[i] && scene->top.nodes) {
                kdrt_hit hit;
                kdrt__miss(&hit), hit.t = rays[i].tmax;
                occluded[i] = (uint8_t)kdrt__walk_instances(scene, &rays[i], query, &hit, 1, NULL);
            }
            found += occluded[i];
        }
        return found;
    }
    for (i = 0; i < count; ++i) {
        occluded[i] = (uint8_t)(scene && rays && kdrt_scene_occluded(scene, &rays[i], query));
        found += occluded[i];
    }
    return found;
}

KDRT_API uint32_t kdrt_scene_intersect_k(const kdrt_scene *scene, const kdrt_ray *ray,
                                         const kdrt_query *query, kdrt_hit *hits,
                                         uint32_t capacity)
{
    kdrt__hit_list list;
    kdrt_hit bound;
    if (!scene || !ray || !hits || capacity == 0) return 0;
    list.hits = hits, list.count = 0, list.capacity = capacity;
    kdrt__scene_query(scene, ray, query, &bound, 0, &list);
    return list.count;
}

KDRT_API int kdrt_scene_hit_surface(const kdrt_scene *scene, const kdrt_hit *hit, float point[3],
                                    float normal[3])
{
    const kdrt_geometry *e;
    float p[3][3];
    if (!scene || !hit) return 0;
    if (hit->instance != KDRT_INVALID_ID) {
        const kdrt__instance *in = kdrt__find_instance(scene, hit->instance);
        if (!in || hit->geometry != hit->instance ||
            !kdrt__hit_corners(&in->tree->meshes.parts[0].mesh, hit->triangle, p))
            return 0;
        kdrt__surface(p, in, hit->u, hit->v, point, normal);
        return 1;
    }
    e = kdrt__find_entry(scene, hit->geometry);
    if (!e || e->type != KDRT_GEOMETRY_MESH ||
        !kdrt__hit_corners(&scene->now.parts[scene->now.slot[e - scene->now.entries]].mesh,
                           hit->triangle, p))
        return 0;
    kdrt__surface(p, NULL, hit->u, hit->v, point, normal);
    return 1;
}

KDRT_API int kdrt_scene_spawn_ray(const kdrt_scene *scene, const kdrt_hit *hit, const float dir[3],
                                  kdrt_ray *out)
{
    float point[3], normal[3];
    if (!out) return 0;
    memset(out, 0, sizeof *out);
    if (!dir || !kdrt_scene_hit_surface(scene, hit, point, normal)) return 0;
    kdrt__leave_surface(point, normal, dir, out);
    out->cell = kdrt__spawn_cell(scene->meshes, hit->instance == KDRT_INVALID_ID ? hit->cell : 0,
                                 out->org);
    return 1;
}

KDRT_API uint32_t kdrt_scene_locate(const kdrt_scene *scene, const float point[3])
{
    return scene ? kdrt_locate(scene->meshes, point) : 0;
}

/* ==== closest point and overlap: exact signs, the distance to a triangle, the walks ==== */

/* -- Exact signs of sums of exact doubles (CLOSEST POINT AND OVERLAP) -- */

/* a + b = *s + *e exactly (Knuth's TwoSum, for round to nearest without overflow). */
static void kdrt__two_sum(double a, double b, double *s, double *e)
{
    const double x = a + b, bv = x - a, av = x - bv;
    *s = x;
    *e = (a - av) + (b - bv);
}

/* The sign (-1, 0 or 1) of t[0] + ... + t[n - 1], each term an exact double (a product of two
   floats, or a part of one of three), n at most KDRT__SUM_MAX. The sum in double decides when it
   is farther from 0 than its rounding error can reach ((n - 1) 2^-53 of the sum of the
   magnitudes, bounded by n 2^-52); otherwise the terms are summed exactly, by Shewchuk's
   grow-expansion (1997), into components that do not overlap, in increasing magnitude, and the
   largest nonzero one has the sum's sign. Terms up to 2^116 and down to 2^-447 (products of
   floats) neither overflow nor lose a bit. t is overwritten. */
#define KDRT__SUM_MAX 48
static int kdrt__sign_of_sum(double *t, int n)
{
    double s = 0.0, m = 0.0;
    int i, j;
    for (i = 0; i < n; ++i) s += t[i], m += fabs(t[i]);
    if (fabs(s) > (double)n * 2.220446049250313e-16 * m) return s > 0.0 ? 1 : -1;
    if (m == 0.0) return 0;
    for (i = 0; i < n; ++i) {
        /* t[0 .. i) is the expansion so far; t[i] goes through it and ends on top. */
        double q = t[i];
        for (j = 0; j < i; ++j) kdrt__two_sum(q, t[j], &q, &t[j]);
        t[i] = q;
    }
    for (i = n - 1; i >= 0; --i)
        if (t[i] != 0.0) return t[i] > 0.0 ? 1 : -1;
    return 0;
}

/* The sign of (Q_w - P_w)(X_u - Y_u) - (Q_u - P_u)(X_w - Y_w), exactly: multiplied out into
   eight products of floats, each exact in double. */
static int kdrt__sign_area(const float P[3], const float Q[3], const float X[3], const float Y[3],
                           int u, int w)
{
    double t[8];
    t[0] = (double)Q[w] * X[u], t[1] = -(double)Q[w] * Y[u];
    t[2] = -(double)P[w] * X[u], t[3] = (double)P[w] * Y[u];
    t[4] = -(double)Q[u] * X[w], t[5] = (double)Q[u] * Y[w];
    t[6] = (double)P[u] * X[w], t[7] = -(double)P[u] * Y[w];
    return kdrt__sign_of_sum(t, 8);
}

/* The 6 products of det(x, y, z) (rows), each product of three floats as two doubles whose sum
   it is exactly (the first two factors' product is exact, the third's by fma), times sign. */
static int kdrt__det_terms(const float x[3], const float y[3], const float z[3], double sign,
                           double *t)
{
    static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    static const double parity[6] = {1.0, -1.0, -1.0, 1.0, 1.0, -1.0};
    int k;
    for (k = 0; k < 6; ++k) {
        const double xy = sign * parity[k] * ((double)x[perm[k][0]] * y[perm[k][1]]);
        const double p = xy * z[perm[k][2]];
        t[2 * k] = p;
        t[2 * k + 1] = fma(xy, (double)z[perm[k][2]], -p);
    }
    return 12;
}

/* The sign of ((b - a) x (c - a)) . (v - a), exactly: which side of the triangle's plane v is
   on. The filter is Shewchuk's orient3d bound; when it cannot decide, the determinant is
   det(b, c, v) - det(b, c, a) - det(b, a, v) - det(a, c, v), 24 products of three floats. */
static int kdrt__orient3d(const float a[3], const float b[3], const float c[3], const float v[3])
{
    const double adx = (double)a[0] - v[0], ady = (double)a[1] - v[1], adz = (double)a[2] - v[2];
    const double bdx = (double)b[0] - v[0], bdy = (double)b[1] - v[1], bdz = (double)b[2] - v[2];
    const double cdx = (double)c[0] - v[0], cdy = (double)c[1] - v[1], cdz = (double)c[2] - v[2];
    const double bc = bdx * cdy - bdy * cdx, ca = cdx * ady - cdy * adx, ab = adx * bdy - ady * bdx;
    /* det(a - v, b - v, c - v) = -((b - a) x (c - a)) . (v - a) */
    const double det = adz * bc + bdz * ca + cdz * ab;
    const double permanent = (fabs(bdx * cdy) + fabs(bdy * cdx)) * fabs(adz) +
                             (fabs(cdx * ady) + fabs(cdy * adx)) * fabs(bdz) +
                             (fabs(adx * bdy) + fabs(ady * bdx)) * fabs(cdz);
    const double bound = 7.771561172376103e-16 /* (7 + 56 2^-53) 2^-53 */ * permanent;
    double t[KDRT__SUM_MAX];
    int n = 0;
    if (det > bound) return -1;
    if (-det > bound) return 1;
    n += kdrt__det_terms(b, c, v, 1.0, t + n);
    n += kdrt__det_terms(b, c, a, -1.0, t + n);
    n += kdrt__det_terms(b, a, v, -1.0, t + n);
    n += kdrt__det_terms(a, c, v, -1.0, t + n);
    return kdrt__sign_of_sum(t, n);
}

/* 1 when the triangle p meets the closed box [lo, hi] (finite, lo <= hi): the separating axis
   test (Akenine-Moeller 2001), its 13 axes' decisions each exact. Box axes compare floats;
   the triangle's normal, found by the exact signs of its components, picks the box's two
   corners extreme along it, whose sides of the plane kdrt__orient3d gives; each edge crossed
   with each box axis is a line in the plane across that axis, against which the box's extreme
   corner and the third corner are placed by kdrt__sign_area. Touching is meeting. */
static int kdrt__triangle_box(float p[3][3], const float lo[3], const float hi[3])
{
    float vmin[3], vmax[3];
    int a, i, within = 1;
    for (a = 0; a < 3; ++a) {
        const float mn = p[0][a] < p[1][a] ? (p[0][a] < p[2][a] ? p[0][a] : p[2][a])
                                           : (p[1][a] < p[2][a] ? p[1][a] : p[2][a]);
        const float mx = p[0][a] > p[1][a] ? (p[0][a] > p[2][a] ? p[0][a] : p[2][a])
                                           : (p[1][a] > p[2][a] ? p[1][a] : p[2][a]);
        if (mn > hi[a] || mx < lo[a]) return 0;
        within &= mn >= lo[a] && mx <= hi[a];
    }
    if (within) return 1; /* every corner in the box */
    for (a = 0; a < 3; ++a) {
        /* n[a] = (b - a)_u (c - a)_w - (b - a)_w (c - a)_u, multiplied out */
        const int u = (a + 1) % 3, w = (a + 2) % 3;
        double t[6];
        int s;
        t[0] = (double)p[1][u] * p[2][w], t[1] = -(double)p[1][u] * p[0][w];
        t[2] = -(double)p[0][u] * p[2][w], t[3] = -(double)p[1][w] * p[2][u];
        t[4] = (double)p[1][w] * p[0][u], t[5] = (double)p[0][w] * p[2][u];
        s = kdrt__sign_of_sum(t, 6);
        vmin[a] = s > 0 ? lo[a] : hi[a], vmax[a] = s > 0 ? hi[a] : lo[a];
    }
    if (kdrt__orient3d(p[0], p[1], p[2], vmin) > 0) return 0; /* the box above the plane */
    if (kdrt__orient3d(p[0], p[1], p[2], vmax) < 0) return 0; /* below it */
    for (i = 0; i < 3; ++i) {
        const float *P = p[i], *Q = p[(i + 1) % 3], *R = p[(i + 2) % 3];
        for (a = 0; a < 3; ++a) {
            /* Across axis a: the line through P and Q in the (u, w) plane, along which
               s(X) = e_w X_u - e_u X_w is constant (e = Q - P). */
            const int u = (a + 1) % 3, w = (a + 2) % 3;
            float lo_x[3], hi_x[3];
            if (Q[u] == P[u] && Q[w] == P[w]) continue; /* the edge along the axis: no line */
            lo_x[a] = hi_x[a] = 0.0f;
            lo_x[u] = Q[w] >= P[w] ? lo[u] : hi[u], hi_x[u] = Q[w] >= P[w] ? hi[u] : lo[u];
            lo_x[w] = Q[u] >= P[u] ? hi[w] : lo[w], hi_x[w] = Q[u] >= P[u] ? lo[w] : hi[w];
            if (kdrt__sign_area(P, Q, lo_x, P, u, w) > 0 && kdrt__sign_area(P, Q, lo_x, R, u, w) > 0)
                return 0;
            if (kdrt__sign_area(P, Q, hi_x, P, u, w) < 0 && kdrt__sign_area(P, Q, hi_x, R, u, w) < 0)
                return 0;
        }
    }
    return 1;
}

/* -- The distance from a point to a triangle (CLOSEST POINT AND OVERLAP) -- */

/* a b - c d with one rounding's error at most 1.5 ulps (Kahan's, by fma): no cancellation. */
static KDRT__FORCEINLINE double kdrt__dop(double a, double b, double c, double d)
{
    const double w = c * d;
    return fma(a, b, -w) + fma(-c, d, w);
}
static KDRT__FORCEINLINE void kdrt__cross_accurate(const double x[3], const double y[3],
                                                   double out[3])
{
    out[0] = kdrt__dop(x[1], y[2], x[2], y[1]);
    out[1] = kdrt__dop(x[2], y[0], x[0], y[2]);
    out[2] = kdrt__dop(x[0], y[1], x[1], y[0]);
}
static KDRT__FORCEINLINE double kdrt__dot3(const double x[3], const double y[3])
{
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
}
static KDRT__FORCEINLINE double kdrt__norm3(const double x[3])
{
    return sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
}

/* The distance from the origin to the segment S + t e, t in [0, 1], whose end is E (= S + e up
   to rounding: the ends are returned as they are given, so that a corner shared by triangles
   gives each the same distance); its t in *t. */
static KDRT__FORCEINLINE double kdrt__origin_segment(const double S[3], const double e[3],
                                                     const double E[3], double *t)
{
    const double ee = kdrt__dot3(e, e), se = -kdrt__dot3(S, e);
    double x, d[3];
    int k;
    if (!(se > 0.0) || ee == 0.0) return *t = 0.0, kdrt__norm3(S);
    if (se >= ee) return *t = 1.0, kdrt__norm3(E);
    x = se / ee;
    for (k = 0; k < 3; ++k) d[k] = S[k] + x * e[k];
    *t = x;
    return kdrt__norm3(d);
}

/* The distance from point to the triangle with corners c (floats), and the barycentrics (u, v)
   of its nearest point. Ericson's regions (Real-Time Collision Detection, 5.1.5), decided in the
   point's own frame so that the error is bounded by the size of the triangle seen from the
   point, not from the origin: the corners moved by -point in double (one rounding each); the
   point's foot on the plane is inside when the three signed areas it makes with the edges,
   (B x (C - B)) . n and its turns (n = (B - A) x (C - A)), are at least 0 and not all 0, and
   the distance is then |n . A| / |n|; otherwise it is the nearest of the three edges. The cross
   products are formed by fma with one rounding a component, so slivers keep their normals.
   Error: see CLOSEST POINT AND OVERLAP. */
static KDRT__FORCEINLINE double kdrt__point_triangle(float c[3][3], const float point[3], double *u,
                                                     double *v)
{
    double A[3], B[3], C[3], e0[3], e1[3], e2[3], n[3], m[3], nn, d, t, best, bu, bv;
    int k;
    for (k = 0; k < 3; ++k) {
        A[k] = (double)c[0][k] - point[k];
        B[k] = (double)c[1][k] - point[k];
        C[k] = (double)c[2][k] - point[k];
    }
    for (k = 0; k < 3; ++k) e0[k] = B[k] - A[k], e1[k] = C[k] - A[k], e2[k] = C[k] - B[k];
    kdrt__cross_accurate(e0, e1, n);
    nn = kdrt__dot3(n, n);
    if (nn > 0.0) {
        double la, lb, lc;
        kdrt__cross_accurate(B, e2, m);
        la = kdrt__dot3(m, n);
        kdrt__cross_accurate(e1, C, m);
        lb = kdrt__dot3(m, n);
        kdrt__cross_accurate(A, e0, m);
        lc = kdrt__dot3(m, n);
        /* All three 0 (a point on a corner, with an edge the rounding turned parallel to
           another): no barycentrics from them, the edges decide. */
        if (la >= 0.0 && lb >= 0.0 && lc >= 0.0 && la + lb + lc > 0.0) {
            const double s = la + lb + lc;
            *u = lb / s, *v = lc / s;
            return fabs(kdrt__dot3(n, A)) / sqrt(nn);
        }
    }
    /* Outside (or a triangle the rounding made flat): the nearest edge, the first on a tie. */
    best = kdrt__origin_segment(A, e0, B, &t), bu = t, bv = 0.0;
    d = kdrt__origin_segment(A, e1, C, &t);
    if (d < best) best = d, bu = 0.0, bv = t;
    d = kdrt__origin_segment(B, e2, C, &t);
    if (d < best) best = d, bu = 1.0 - t, bv = t;
    *u = bu, *v = bv;
    return best;
}

/* The point at barycentrics (u, v) of the triangle c, in double, kept within its corners' box
   (as kdrt__surface does), rounded to float. */
static void kdrt__triangle_point(float c[3][3], double u, double v, float out[3])
{
    int a;
    for (a = 0; a < 3; ++a) {
        const double x = c[0][a] + u * ((double)c[1][a] - c[0][a]) + v * ((double)c[2][a] - c[0][a]);
        const float lo = c[0][a] < c[1][a] ? (c[0][a] < c[2][a] ? c[0][a] : c[2][a])
                                           : (c[1][a] < c[2][a] ? c[1][a] : c[2][a]);
        const float hi = c[0][a] > c[1][a] ? (c[0][a] > c[2][a] ? c[0][a] : c[2][a])
                                           : (c[1][a] > c[2][a] ? c[1][a] : c[2][a]);
        out[a] = (float)(x < lo ? lo : (x > hi ? hi : x));
    }
}

/* 1 when the triangle c meets the closed ball (center, radius), radius finite: a corner in the
   ball, decided exactly (|p - center|^2 - radius^2 multiplied out: ten exact products), or the
   distance of kdrt__point_triangle at most radius. A triangle whose box lies beyond radius
   (in double, with a margin of 2^-40 for its rounding) is left out first. */
static int kdrt__triangle_ball(float c[3][3], const float center[3], float radius)
{
    double d2 = 0.0, u, v, t[10];
    int a, k;
    for (a = 0; a < 3; ++a) {
        const float lo = c[0][a] < c[1][a] ? (c[0][a] < c[2][a] ? c[0][a] : c[2][a])
                                           : (c[1][a] < c[2][a] ? c[1][a] : c[2][a]);
        const float hi = c[0][a] > c[1][a] ? (c[0][a] > c[2][a] ? c[0][a] : c[2][a])
                                           : (c[1][a] > c[2][a] ? c[1][a] : c[2][a]);
        const double x = center[a] < lo ? (double)lo - center[a]
                                        : (center[a] > hi ? (double)center[a] - hi : 0.0);
        d2 += x * x;
    }
    if (d2 * (1.0 - 9.094947017729282e-13) > (double)radius * radius) return 0;
    for (k = 0; k < 3; ++k) {
        for (a = 0; a < 3; ++a) {
            t[3 * a] = (double)c[k][a] * c[k][a];
            t[3 * a + 1] = -2.0 * ((double)c[k][a] * center[a]);
            t[3 * a + 2] = (double)center[a] * center[a];
        }
        t[9] = -((double)radius * radius);
        if (kdrt__sign_of_sum(t, 10) <= 0) return 1;
    }
    return kdrt__point_triangle(c, center, &u, &v) <= (double)radius;
}

/* -- The walks (CLOSEST POINT AND OVERLAP) -- */

/* A node waiting on a walk's stack, with its box (the tree's bounds cut by the splits above it)
   and, for the overlap walk, which of its faces are split planes (bit 2 a: the face at lo[a],
   bit 2 a + 1: at hi[a]; the others are faces of the tree's bounds). */
typedef struct kdrt__box_todo {
    uint32_t node, faces;
    float lo[3], hi[3];
} kdrt__box_todo;

/* A node waiting in the closest-point walk's queue: the distances from the query's point to its
   box along each axis (0 within its extent), whose squares sum to the box's squared distance,
   its key in the queue. */
typedef struct kdrt__point_todo {
    double box2, off[3];
    uint32_t node;
} kdrt__point_todo;

/* The closest-point walk's queue holds this many nodes (more are rare: see
   kdrt__closest_walk_body); at least KDRT_MAX_DEPTH + 1, the stack of its depth-first form. */
#define KDRT__POINT_QUEUE 128

/* todo[0, *count) in decreasing box2, the nearest last (taken out from the end): e put in its
   place, found from the end. A node's farther child, queued on the way down, is mostly nearer
   than those waiting, so this costs a comparison or two, less than a heap's sifting. */
static KDRT__FORCEINLINE void kdrt__point_queue(kdrt__point_todo *todo, uint32_t *count,
                                                const kdrt__point_todo *e)
{
    uint32_t i = (*count)++;
    for (; i > 0 && todo[i - 1].box2 < e->box2; --i) todo[i] = todo[i - 1];
    todo[i] = *e;
}

/* The margin of the walks' pruning: a node or a triangle is left out only when its distance,
   less 2^-40 of it, exceeds the best so far (in a tree's walk, the best plus a margin for the
   reach of a far corner: kdrt__closest_walk_body), so that rounding never prunes a triangle
   whose computed distance would tie or win. */
#define KDRT__PRUNE_SLACK (1.0 - 9.094947017729282e-13)

/* The distance from y to the box [lo, hi], in double. */
static double kdrt__box_distance(const double y[3], const float lo[3], const float hi[3])
{
    double d2 = 0.0;
    int a;
    for (a = 0; a < 3; ++a) {
        const double x = y[a] < lo[a] ? lo[a] - y[a] : (y[a] > hi[a] ? y[a] - hi[a] : 0.0);
        d2 += x * x;
    }
    return sqrt(d2);
}

/* A leaf lane's corners: the tree's, or carried into the world by the instance in and rounded
   to float (the triangle an instance stands for in these queries: CLOSEST POINT AND OVERLAP). */
static void kdrt__lane_world(const kdrt__block *block, uint32_t lane, const kdrt__instance *in,
                               float object[3][3], float world[3][3])
{
    int k, a;
    for (k = 0; k < 3; ++k)
        for (a = 0; a < 3; ++a) object[k][a] = block->corner[3 * k + a][lane];
    for (k = 0; k < 3; ++k)
        for (a = 0; a < 3; ++a)
            world[k][a] = in ? (float)(in->to_world[4 * a] * object[k][0] +
                                       in->to_world[4 * a + 1] * object[k][1] +
                                       in->to_world[4 * a + 2] * object[k][2] + in->to_world[4 * a + 3])
                             : object[k][a];
}

/* How far an instance's world triangles (corners rounded to float) may lie from the exact image
   of its tree's triangles: the float rounding of a corner (2^-24 of the world box's largest
   coordinate) and the double evaluation's (2^-50 of |R| |p| + |t|), each component, times 2 for
   the three components' length. */
static double kdrt__instance_slop(const kdrt__instance *in)
{
    const kdrt_aabb *tb = &in->tree->bounds;
    double big = 0.0, p = 0.0, sum = 0.0;
    int a, j;
    for (a = 0; a < 3; ++a) {
        big = fabs(in->box.min[a]) > big ? fabs(in->box.min[a]) : big;
        big = fabs(in->box.max[a]) > big ? fabs(in->box.max[a]) : big;
        p = fabs(tb->min[a]) > p ? fabs(tb->min[a]) : p;
        p = fabs(tb->max[a]) > p ? fabs(tb->max[a]) : p;
    }
    for (a = 0; a < 3; ++a) {
        double row = fabs(in->to_world[4 * a + 3]);
        for (j = 0; j < 3; ++j) row += fabs(in->to_world[4 * a + j]) * p;
        sum = row > sum ? row : sum;
    }
    return 2.0 * (5.960464477539063e-08 /* 2^-24 */ * big + 8.881784197001252e-16 /* 2^-50 */ * sum);
}

/* The best triangle of a closest-point query so far, ordered by (distance, key, triangle). */
typedef struct kdrt__closest_best {
    double distance, u, v; /* before one is found: the bound the walk prunes by */
    float limit;            /* max_distance, which the first one's rounded distance must meet */
    uint32_t key, triangle, instance;
    int found;
    float corners[3][3]; /* its corners in the world, for the point */
    /* The supporting-plane bound (kdrt__closest_walk_body): w, about the best point less the
       query's point, and its length, when plane is 1; 0 when the best changed since. */
    double w[3], w_length;
    int plane;
} kdrt__closest_best;

/* Sets best's w to its point less q (the query's point in the world), for the supporting-plane
   bound; plane stays 0 when that is 0 or not finite. */
static void kdrt__closest_plane(kdrt__closest_best *best, const float q[3])
{
    double n2 = 0.0;
    int a;
    for (a = 0; a < 3; ++a) {
        const double c0 = best->corners[0][a];
        best->w[a] = c0 + best->u * ((double)best->corners[1][a] - c0) +
                     best->v * ((double)best->corners[2][a] - c0) - q[a];
        n2 += best->w[a] * best->w[a];
    }
    best->w_length = sqrt(n2);
    best->plane = best->w_length > 0.0 && best->w_length < INFINITY ? 1 : -1;
}

/* The supporting-plane bound of block's lane: for any vector w, |x - y| >= w . (x - y) / |w|,
   and over the triangle w . (x - y) is least at a corner. Returns that least w . (c - y), each
   lowered by 2^-48 of the sum of its terms' magnitudes (more than its rounding): divided by |w|
   raised by 2^-48 (more than its rounding), a bound of the exact distance whatever w is. With w
   the best point less y, triangles behind the best one's supporting plane (most of a convex
   surface's, seen from outside) are left out without measuring them. */
static KDRT__FORCEINLINE double kdrt__plane_least(const kdrt__block *block, uint32_t lane,
                                                  const double y[3], const double w[3])
{
    double least = INFINITY;
    int k, a;
    for (k = 0; k < 3; ++k) {
        double t = 0.0, m = 0.0;
        for (a = 0; a < 3; ++a) {
            const double x = w[a] * ((double)block->corner[3 * k + a][lane] - y[a]);
            t += x, m += fabs(x);
        }
        t -= 3.552713678800501e-15 /* 2^-48 */ * m;
        least = t < least ? t : least;
    }
    return least;
}

/* The squared pruning margin: 2^-38 on a squared distance, more than KDRT__PRUNE_SLACK's 2^-40 on
   the distance with the squares' roundings. */
#define KDRT__PRUNE_SLACK2 (1.0 - 3.637978807091713e-12)

/* Which of a leaf block's first `lanes` lanes are left in (bit lane set) by the best distance so
   far, limit: a lane is out when the squared distance from q to its box (its corners' box),
   times KDRT__PRUNE_SLACK2, exceeds limit squared, or when w_length > 0 and its supporting-plane
   bound (kdrt__plane_least over w_length raised by 2^-48), times KDRT__PRUNE_SLACK, exceeds
   limit, compared multiplied out: no square root, no division. box2[lane] is the first of the
   two, for lanes in. y is q in double. */
static unsigned kdrt__block_bounds(const kdrt__block *block, uint32_t lanes, const float q[3],
                                   const double y[3], const double w[3], double w_length,
                                   double limit, double box2[KDRT__LANES])
{
    const double limit2 = limit * limit, plane_limit = limit * (w_length * (1.0 + 3.552713678800501e-15));
    unsigned left = 0;
    uint32_t lane;
    int a, k;
    for (lane = 0; lane < lanes; ++lane) {
        double d2 = 0.0;
        for (a = 0; a < 3; ++a) {
            float lo = block->corner[a][lane], hi = lo;
            double d;
            for (k = 1; k < 3; ++k) {
                const float c = block->corner[3 * k + a][lane];
                lo = c < lo ? c : lo;
                hi = c > hi ? c : hi;
            }
            d = q[a] < lo ? (double)lo - q[a] : (q[a] > hi ? (double)q[a] - hi : 0.0);
            d2 += d * d;
        }
        box2[lane] = d2 * KDRT__PRUNE_SLACK2;
        if (box2[lane] > limit2) continue;
        if (w_length > 0.0 && kdrt__plane_least(block, lane, y, w) * KDRT__PRUNE_SLACK > plane_limit)
            continue;
        left |= 1u << lane;
    }
    return left;
}

#ifdef KDRT__AVX2
/* The same, 4 lanes at a time in double with AVX2: the same operations on the same values (the
   corners widened exactly, one rounding a subtraction, product and sum), so the same lanes; the
   plane bounds of a half only when its boxes leave a lane in. */
KDRT__TARGET_AVX2 static unsigned kdrt__block_bounds_avx2(const kdrt__block *block, uint32_t lanes,
                                                          const float q[3], const double y[3],
                                                          const double w[3], double w_length,
                                                          double limit, double box2[KDRT__LANES])
{
    const __m256d zero = _mm256_setzero_pd(), slack = _mm256_set1_pd(KDRT__PRUNE_SLACK);
    const __m256d slack2 = _mm256_set1_pd(KDRT__PRUNE_SLACK2);
    const __m256d sign = _mm256_set1_pd(-0.0), margin = _mm256_set1_pd(3.552713678800501e-15);
    const __m256d limit2 = _mm256_set1_pd(limit * limit);
    const __m256d plane_limit = _mm256_set1_pd(limit * (w_length * (1.0 + 3.552713678800501e-15)));
    const unsigned in_leaf = lanes >= KDRT__LANES ? 0xFFu : (1u << lanes) - 1u;
    unsigned left = 0;
    int half, a, k;
    for (half = 0; half < 2 && 4 * half < (int)lanes; ++half) {
        __m256d d2 = zero;
        unsigned near;
        for (a = 0; a < 3; ++a) {
            const __m128 c0 = _mm_loadu_ps(&block->corner[a][4 * half]);
            const __m128 c1 = _mm_loadu_ps(&block->corner[3 + a][4 * half]);
            const __m128 c2 = _mm_loadu_ps(&block->corner[6 + a][4 * half]);
            const __m256d lo = _mm256_cvtps_pd(_mm_min_ps(_mm_min_ps(c0, c1), c2));
            const __m256d hi = _mm256_cvtps_pd(_mm_max_ps(_mm_max_ps(c0, c1), c2));
            const __m256d yq = _mm256_set1_pd((double)q[a]);
            const __m256d d =
                _mm256_max_pd(_mm256_max_pd(_mm256_sub_pd(lo, yq), _mm256_sub_pd(yq, hi)), zero);
            d2 = _mm256_add_pd(d2, _mm256_mul_pd(d, d));
        }
        d2 = _mm256_mul_pd(d2, slack2);
        _mm256_storeu_pd(box2 + 4 * half, d2);
        near = (unsigned)_mm256_movemask_pd(_mm256_cmp_pd(d2, limit2, _CMP_LE_OQ)) << (4 * half);
        if (near & in_leaf && w_length > 0.0) {
            __m256d least = _mm256_set1_pd(INFINITY);
            for (k = 0; k < 3; ++k) {
                __m256d t = zero, m = zero;
                for (a = 0; a < 3; ++a) {
                    const __m256d c =
                        _mm256_cvtps_pd(_mm_loadu_ps(&block->corner[3 * k + a][4 * half]));
                    const __m256d x =
                        _mm256_mul_pd(_mm256_set1_pd(w[a]), _mm256_sub_pd(c, _mm256_set1_pd(y[a])));
                    t = _mm256_add_pd(t, x), m = _mm256_add_pd(m, _mm256_andnot_pd(sign, x));
                }
                t = _mm256_sub_pd(t, _mm256_mul_pd(margin, m));
                least = _mm256_min_pd(t, least); /* t < least ? t : least */
            }
            least = _mm256_mul_pd(least, slack);
            near &= (unsigned)_mm256_movemask_pd(_mm256_cmp_pd(least, plane_limit, _CMP_LE_OQ))
                    << (4 * half);
        }
        left |= near;
    }
    return left & in_leaf;
}
#endif

#ifdef KDRT__AVX2
/* kdrt__dop and its cross product and kdrt__dot3 and kdrt__norm3, 4 lanes at a time. */
KDRT__TARGET_AVX2_FMA static KDRT__FORCEINLINE __m256d kdrt__dop_x4(__m256d a, __m256d b, __m256d c,
                                                                  __m256d d)
{
    const __m256d w = _mm256_mul_pd(c, d), sign = _mm256_set1_pd(-0.0);
    return _mm256_add_pd(_mm256_fmadd_pd(a, b, _mm256_xor_pd(w, sign)),
                         _mm256_fmadd_pd(_mm256_xor_pd(c, sign), d, w));
}
KDRT__TARGET_AVX2_FMA static KDRT__FORCEINLINE void kdrt__cross_x4(const __m256d x[3],
                                                                   const __m256d y[3], __m256d out[3])
{
    out[0] = kdrt__dop_x4(x[1], y[2], x[2], y[1]);
    out[1] = kdrt__dop_x4(x[2], y[0], x[0], y[2]);
    out[2] = kdrt__dop_x4(x[0], y[1], x[1], y[0]);
}
KDRT__TARGET_AVX2_FMA static KDRT__FORCEINLINE __m256d kdrt__dot_x4(const __m256d x[3],
                                                                   const __m256d y[3])
{
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x[0], y[0]), _mm256_mul_pd(x[1], y[1])),
                         _mm256_mul_pd(x[2], y[2]));
}

/* kdrt__origin_segment, 4 lanes at a time: each lane's branch chosen by blending, its distance
   the square root of the same sums of the same values; t in *t. */
KDRT__TARGET_AVX2_FMA static KDRT__FORCEINLINE __m256d kdrt__origin_segment_x4(const __m256d S[3],
                                                                              const __m256d e[3],
                                                                              const __m256d E[3],
                                                                              __m256d *t)
{
    const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
    const __m256d ee = kdrt__dot_x4(e, e);
    const __m256d se = _mm256_xor_pd(kdrt__dot_x4(S, e), _mm256_set1_pd(-0.0));
    /* !(se > 0) || ee == 0: the start; else se >= ee: the end; else S + x e, x = se / ee */
    const __m256d at_start =
        _mm256_or_pd(_mm256_cmp_pd(se, zero, _CMP_NGT_UQ), _mm256_cmp_pd(ee, zero, _CMP_EQ_OQ));
    const __m256d at_end = _mm256_andnot_pd(at_start, _mm256_cmp_pd(se, ee, _CMP_GE_OQ));
    const __m256d x = _mm256_div_pd(se, ee);
    __m256d p[3];
    int k;
    for (k = 0; k < 3; ++k) {
        p[k] = _mm256_add_pd(S[k], _mm256_mul_pd(x, e[k]));
        p[k] = _mm256_blendv_pd(_mm256_blendv_pd(p[k], E[k], at_end), S[k], at_start);
    }
    *t = _mm256_blendv_pd(_mm256_blendv_pd(x, one, at_end), zero, at_start);
    return _mm256_sqrt_pd(kdrt__dot_x4(p, p));
}

/* kdrt__point_triangle for lanes 4 half to 4 half + 3 of block from q, 4 at a time with AVX2 and
   FMA: the same operations on the same values, every branch taken and each lane's own kept, so
   the same distances and barycentrics bit for bit. */
KDRT__TARGET_AVX2_FMA static void kdrt__point_triangles_avx2(const kdrt__block *block, int half,
                                                            const float q[3], double d[4],
                                                            double u[4], double v[4])
{
    const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
    __m256d A[3], B[3], C[3], e0[3], e1[3], e2[3], n[3], m[3], nn, la, lb, lc, s, inside;
    __m256d plane, best, bu, bv, t, x;
    int k;
    for (k = 0; k < 3; ++k) {
        const __m256d p = _mm256_set1_pd((double)q[k]);
        A[k] = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(&block->corner[k][4 * half])), p);
        B[k] = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(&block->corner[3 + k][4 * half])), p);
        C[k] = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(&block->corner[6 + k][4 * half])), p);
    }
    for (k = 0; k < 3; ++k) {
        e0[k] = _mm256_sub_pd(B[k], A[k]);
        e1[k] = _mm256_sub_pd(C[k], A[k]);
        e2[k] = _mm256_sub_pd(C[k], B[k]);
    }
    kdrt__cross_x4(e0, e1, n);
    nn = kdrt__dot_x4(n, n);
    kdrt__cross_x4(B, e2, m);
    la = kdrt__dot_x4(m, n);
    kdrt__cross_x4(e1, C, m);
    lb = kdrt__dot_x4(m, n);
    kdrt__cross_x4(A, e0, m);
    lc = kdrt__dot_x4(m, n);
    s = _mm256_add_pd(_mm256_add_pd(la, lb), lc);
    inside = _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(nn, zero, _CMP_GT_OQ),
                                         _mm256_cmp_pd(la, zero, _CMP_GE_OQ)),
                           _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(lb, zero, _CMP_GE_OQ),
                                                       _mm256_cmp_pd(lc, zero, _CMP_GE_OQ)),
                                         _mm256_cmp_pd(s, zero, _CMP_GT_OQ)));
    plane = _mm256_div_pd(_mm256_andnot_pd(_mm256_set1_pd(-0.0), kdrt__dot_x4(n, A)),
                          _mm256_sqrt_pd(nn));
    /* the nearest edge, the first on a tie */
    best = kdrt__origin_segment_x4(A, e0, B, &t);
    bu = t, bv = zero;
    x = kdrt__origin_segment_x4(A, e1, C, &t);
    {
        const __m256d nearer = _mm256_cmp_pd(x, best, _CMP_LT_OQ);
        best = _mm256_blendv_pd(best, x, nearer);
        bu = _mm256_blendv_pd(bu, zero, nearer), bv = _mm256_blendv_pd(bv, t, nearer);
    }
    x = kdrt__origin_segment_x4(B, e2, C, &t);
    {
        const __m256d nearer = _mm256_cmp_pd(x, best, _CMP_LT_OQ);
        best = _mm256_blendv_pd(best, x, nearer);
        bu = _mm256_blendv_pd(bu, _mm256_sub_pd(one, t), nearer), bv = _mm256_blendv_pd(bv, t, nearer);
    }
    _mm256_storeu_pd(d, _mm256_blendv_pd(best, plane, inside));
    _mm256_storeu_pd(u, _mm256_blendv_pd(bu, _mm256_div_pd(lb, s), inside));
    _mm256_storeu_pd(v, _mm256_blendv_pd(bv, _mm256_div_pd(lc, s), inside));
}
#endif

/* best updated with triangle id (key, instance in) at distance d, barycentrics (u, v), corners
   world, when it comes before best in the (distance, key, triangle) order. */
static KDRT__FORCEINLINE void kdrt__closest_offer(kdrt__closest_best *best, double d, double u,
                                                  double v, uint32_t key, uint32_t id,
                                                  const kdrt__instance *in, float world[3][3])
{
    if (best->found ? d < best->distance ||
                          (d == best->distance &&
                           (key < best->key || (key == best->key && id < best->triangle)))
                    : (float)d <= best->limit) {
        best->distance = d, best->u = u, best->v = v;
        best->key = key, best->triangle = id, best->found = 1;
        best->instance = in ? in->id : KDRT_INVALID_ID;
        memcpy(best->corners, world, sizeof best->corners);
        best->plane = 0;
    }
}

/* 1 when a box at squared distance box2 from the query's point (in the tree's space) may hold a
   triangle nearer than best: its distance times scale, less slop, is a lower bound of their world
   distances (plain: scale 1, slop 0, compared squared). */
static KDRT__FORCEINLINE int kdrt__box_near(double box2, int plain, double scale, double slop,
                                            double best)
{
    if (plain) return !(box2 * KDRT__PRUNE_SLACK2 > best * best);
    return !((sqrt(box2) * scale - slop) * KDRT__PRUNE_SLACK > best);
}

/* One tree's walk for a closest-point query, best first: the nodes waiting in a queue ordered
   by their boxes' distances from the point (kdrt__point_queue), the nearest taken out next, its
   nearer child entered at once (at the same distance) and the farther one queued with its
   distances along the axes (the split axis's from the split plane, the others its parent's: the
   box distance as kdrt__box_distance finds it, bit for bit). A node is skipped when its distance
   (in the tree's space, times scale, less slop: a lower bound of the world distance of any
   triangle it holds, CLOSEST POINT AND OVERLAP) exceeds the best so far, and so is everything
   still queued once the nearest is. When the queue is full (KDRT__POINT_QUEUE: a point about as
   far from most of a fine mesh) a node is left out and, once the queue is done, the walk starts
   again from the root depth first with the best so far (its stack bounded by the depth). Its
   triangles get key and instance; mask against the parts' masks (a scene's mesh tree: triangles
   compared as the tree numbers them, which is the (geometry ID, triangle) order). A tree's own
   triangles (no instance) are pruned a leaf block at a time by their boxes' distances and their
   supporting-plane bounds (kdrt__block_bounds), and with avx2 set, 8 lanes pruned and 4 measured
   at once; an instance's, carried into the world one by one, by their world boxes. Which
   triangles are measured, and in which order, changes the work, never the answer: the best is
   the first in the (distance, key, triangle) order whatever the order it is offered in. */
static KDRT__FORCEINLINE void kdrt__closest_walk_body(const kdrt_tree *tree, const kdrt__instance *in,
                                                      const double y[3], const float q[3],
                                                      double scale, double slop, uint32_t mask,
                                                      uint32_t key, kdrt__closest_best *best,
                                                      int avx2)
{
    kdrt__point_todo todo[KDRT__POINT_QUEUE], root, at;
    uint32_t queued = 0, i, lane;
    int best_first = 1, left_out = 0, a;
    const int check_mask = !tree->masks_full, plain = scale == 1.0 && slop == 0.0;
    double reach = 0.0, margin;
    (void)avx2;
    if (tree->stats.triangles == 0) return;
    /* A measured distance may be off by 2^-44 of the distance from q to the triangle's farthest
       corner (CLOSEST POINT AND OVERLAP), far more than its own rounding for a sliver with a far
       corner: nothing is pruned unless it lies beyond the best by more than 2^-43 of the
       farthest corner of the tree's box (the instance's world box), so that a triangle whose
       measured distance could tie or win is always measured, whatever the tree. */
    for (a = 0; a < 3; ++a) {
        const double lo = in ? in->box.min[a] : tree->bounds.min[a];
        const double hi = in ? in->box.max[a] : tree->bounds.max[a];
        const double x = in ? (double)q[a] : y[a];
        const double f = fabs(x - lo) > fabs(x - hi) ? fabs(x - lo) : fabs(x - hi);
        reach += f * f;
    }
    margin = 1.1368683772161603e-13 /* 2^-43 */ * sqrt(reach);
    root.node = 0;
    for (a = 0; a < 3; ++a) {
        const double lo = tree->bounds.min[a], hi = tree->bounds.max[a];
        root.off[a] = y[a] < lo ? lo - y[a] : (y[a] > hi ? y[a] - hi : 0.0);
    }
    root.box2 = 0.0 + root.off[0] * root.off[0] + root.off[1] * root.off[1] + root.off[2] * root.off[2];
    todo[queued++] = root;
    for (;;) {
        if (queued == 0) {
            if (!left_out) return;
            best_first = left_out = 0; /* again, depth first: see above */
            at = root;
        } else {
            at = todo[--queued];
        }
        if (!kdrt__box_near(at.box2, plain, scale, slop, best->distance + margin)) {
            if (best_first) queued = 0; /* the rest are no nearer */
            continue;
        }
        for (;;) {
            const kdrt__node *n = &tree->nodes[at.node];
            const uint32_t count = kdrt__node_count(n);
            if (!kdrt__node_is_leaf(n)) {
                const uint32_t axis = kdrt__node_axis(n);
                const double split = n->u.split;
                const int below = y[axis] <= split;
                kdrt__point_todo far = at;
                far.off[axis] = below ? split - y[axis] : y[axis] - split;
                far.box2 = 0.0 + far.off[0] * far.off[0] + far.off[1] * far.off[1] + far.off[2] * far.off[2];
                far.node = below ? kdrt__node_above(n) : at.node + 1;
                at.node = below ? at.node + 1 : kdrt__node_above(n);
                if (!kdrt__box_near(far.box2, plain, scale, slop, best->distance + margin)) {
                    /* not worth queueing */
                } else if (!best_first) {
                    KDRT_ASSERT(queued < KDRT_MAX_DEPTH + 1);
                    todo[queued++] = far;
                } else if (queued < KDRT__POINT_QUEUE) {
                    kdrt__point_queue(todo, &queued, &far);
                } else {
                    left_out = 1;
                }
                continue;
            }
            if (!in) {
                for (i = 0; i < count; i += KDRT__LANES) {
                    const kdrt__block *block = &tree->blocks[n->u.first + i / KDRT__LANES];
                    const uint32_t lanes = count - i < KDRT__LANES ? count - i : KDRT__LANES;
                    double box2[KDRT__LANES];
                    double w_length = 0.0;
                    unsigned left;
                    if (best->found && best->plane == 0) kdrt__closest_plane(best, q);
                    if (best->plane > 0) w_length = best->w_length;
#ifdef KDRT__AVX2
                    if (avx2)
                        left = kdrt__block_bounds_avx2(block, lanes, q, y, best->w, w_length,
                                                       best->distance + margin, box2);
                    else
#endif
                        left = kdrt__block_bounds(block, lanes, q, y, best->w, w_length,
                                                  best->distance + margin, box2);
#ifdef KDRT__AVX2
                    if (avx2) { /* the lanes left in each half measured 4 at a time */
                        uint32_t half;
                        for (half = 0; half < 2; ++half) {
                            unsigned these = (left >> (4 * half)) & 0xFu;
                            double ds[4], us[4], vs[4];
                            if (!these) continue;
                            kdrt__point_triangles_avx2(block, (int)half, q, ds, us, vs);
                            for (; these; these &= these - 1u) {
                                const unsigned j = kdrt__ctz(these);
                                float world[3][3];
                                const uint32_t id = block->id[lane = 4 * half + j];
                                int k;
                                if (check_mask && !(kdrt__part_of(&tree->meshes, id)->mask & mask))
                                    continue;
                                for (k = 0; k < 3; ++k)
                                    for (a = 0; a < 3; ++a) world[k][a] = block->corner[3 * k + a][lane];
                                kdrt__closest_offer(best, ds[j], us[j], vs[j], key, id, in, world);
                            }
                        }
                        continue;
                    }
#endif
                    for (; left; left &= left - 1u) {
                        float world[3][3];
                        double d, u, v;
                        uint32_t id;
                        int k;
                        lane = kdrt__ctz(left), id = block->id[lane];
                        if (box2[lane] > (best->distance + margin) * (best->distance + margin))
                            continue; /* a nearer one since */
                        if (check_mask && !(kdrt__part_of(&tree->meshes, id)->mask & mask)) continue;
                        for (k = 0; k < 3; ++k)
                            for (a = 0; a < 3; ++a) world[k][a] = block->corner[3 * k + a][lane];
                        d = kdrt__point_triangle(world, q, &u, &v);
                        kdrt__closest_offer(best, d, u, v, key, id, in, world);
                    }
                }
            } else {
                for (i = 0; i < count; ++i) {
                    const kdrt__block *block = &tree->blocks[n->u.first + i / KDRT__LANES];
                    const uint32_t id = block->id[i % KDRT__LANES];
                    float object[3][3], world[3][3];
                    double d, u, v, d2 = 0.0;
                    lane = i % KDRT__LANES;
                    if (check_mask && !(kdrt__part_of(&tree->meshes, id)->mask & mask)) continue;
                    kdrt__lane_world(block, lane, in, object, world);
                    /* The triangle's box first: most triangles of a leaf are farther than the best. */
                    for (a = 0; a < 3; ++a) {
                        int k;
                        double tlo = world[0][a], thi = world[0][a];
                        for (k = 1; k < 3; ++k) {
                            tlo = world[k][a] < tlo ? world[k][a] : tlo;
                            thi = world[k][a] > thi ? world[k][a] : thi;
                        }
                        d = q[a] < tlo ? tlo - q[a] : (q[a] > thi ? q[a] - thi : 0.0);
                        d2 += d * d;
                    }
                    if (sqrt(d2) * KDRT__PRUNE_SLACK > best->distance + margin) continue;
                    d = kdrt__point_triangle(world, q, &u, &v);
                    kdrt__closest_offer(best, d, u, v, key, id, in, world);
                }
            }
            break;
        }
    }
}

static void kdrt__closest_walk_scalar(const kdrt_tree *tree, const kdrt__instance *in,
                                      const double y[3], const float q[3], double scale,
                                      double slop, uint32_t mask, uint32_t key,
                                      kdrt__closest_best *best)
{
    kdrt__closest_walk_body(tree, in, y, q, scale, slop, mask, key, best, 0);
}

#ifdef KDRT__AVX2
/* The walk compiled for AVX2 and FMA: the blocks' bounds 8 lanes at a time, and the distance's
   fma() one instruction instead of a call (fma is exact: the same answers). */
KDRT__TARGET_AVX2_FMA static void kdrt__closest_walk_avx2(const kdrt_tree *tree, const kdrt__instance *in,
                                    const double y[3], const float q[3], double scale, double slop,
                                    uint32_t mask, uint32_t key, kdrt__closest_best *best)
{
    kdrt__closest_walk_body(tree, in, y, q, scale, slop, mask, key, best, 1);
}

#endif

/* The walk of the tree's kernel: the AVX2 form where the tree runs the AVX2 or AVX-512 kernel
   and the CPU has FMA (tree->closest_fma), else the scalar one; both give the same answers. */
static void kdrt__closest_walk(const kdrt_tree *tree, const kdrt__instance *in, const double y[3],
                               const float q[3], double scale, double slop, uint32_t mask,
                               uint32_t key, kdrt__closest_best *best)
{
#ifdef KDRT__AVX2
    if (tree->closest_fma) {
        kdrt__closest_walk_avx2(tree, in, y, q, scale, slop, mask, key, best);
        return;
    }
#endif
    kdrt__closest_walk_scalar(tree, in, y, q, scale, slop, mask, key, best);
}

/* kdrt_closest_point()'s checks (queried: the tree or scene) and its answer from best. out is
   "nothing found" until the walk finds something. */
static kdrt_result kdrt__closest_start(const void *queried, const float point[3],
                                       float max_distance, kdrt_closest *out,
                                       kdrt__closest_best *best)
{
    memset(out, 0, sizeof *out);
    out->triangle = out->instance = KDRT_INVALID_ID;
    out->distance = INFINITY;
    if (!queried || !point) return KDRT_ERROR_NULL_ARGUMENT;
    memset(best, 0, sizeof *best);
    /* The distance returned is rounded to float: one at max_distance after rounding counts. */
    best->limit = max_distance;
    best->distance = max_distance < FLT_MAX ? (double)kdrt__next_up(max_distance) : INFINITY;
    if (!kdrt__finite(point[0]) || !kdrt__finite(point[1]) || !kdrt__finite(point[2]) ||
        !(max_distance >= 0.0f))
        return KDRT_ERROR_INVALID_QUERY;
    return KDRT_SUCCESS;
}
static void kdrt__closest_finish(const kdrt__closest_best *best, kdrt_closest *out)
{
    float corners[3][3];
    if (!best->found) return;
    memcpy(corners, best->corners, sizeof corners);
    out->distance = (float)best->distance;
    out->u = (float)best->u, out->v = (float)best->v;
    out->triangle = best->triangle;
    out->geometry = best->key;
    out->instance = best->instance;
    kdrt__triangle_point(corners, best->u, best->v, out->point);
}

KDRT_API kdrt_result kdrt_closest_point(const kdrt_tree *tree, const float point[3],
                                        float max_distance, kdrt_closest *out)
{
    kdrt__closest_best best;
    kdrt_result r;
    double y[3];
    if (!out) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__closest_start(tree, point, max_distance, out, &best);
    if (r != KDRT_SUCCESS) return r;
    y[0] = point[0], y[1] = point[1], y[2] = point[2];
    kdrt__closest_walk(tree, NULL, y, point, 1.0, 0.0, 0xFFFFFFFFu, 0, &best);
    kdrt__closest_finish(&best, out);
    return KDRT_SUCCESS;
}

/* An overlap query as one tree's walk sees it. */
typedef struct kdrt__overlap_query {
    /* The world's shape: a box [lo, hi] (finite, lo <= hi) or, when sphere, the ball. */
    float lo[3], hi[3];
    int sphere;
    float center[3], radius;
    uint32_t mask;
    kdrt_overlap_fn callback;
    void *user;
    uint64_t count;
    int stopped;
} kdrt__overlap_query;

/* 1 when the closed boxes [alo, ahi] and [blo, bhi] meet. */
static int kdrt__boxes_meet(const float alo[3], const float ahi[3], const float blo[3],
                            const float bhi[3])
{
    return alo[0] <= bhi[0] && blo[0] <= ahi[0] && alo[1] <= bhi[1] && blo[1] <= ahi[1] &&
           alo[2] <= bhi[2] && blo[2] <= ahi[2];
}

/* The leaves of a tree whose boxes meet a query box, in node order (below child first): the
   overlap walk's, and the search for the leaf that reports a triangle. After each
   kdrt__box_walk_next(), lo, hi and faces are the leaf's. */
typedef struct kdrt__box_walk {
    kdrt__box_todo stack[KDRT_MAX_DEPTH + 1];
    uint32_t sp, node, faces; /* node: the next to look at, KDRT_INVALID_ID: pop one first */
    float lo[3], hi[3];
} kdrt__box_walk;

static void kdrt__box_walk_start(kdrt__box_walk *w, const kdrt_tree *tree)
{
    int a;
    w->sp = 0, w->node = 0, w->faces = 0;
    for (a = 0; a < 3; ++a) w->lo[a] = tree->bounds.min[a], w->hi[a] = tree->bounds.max[a];
}

/* The next leaf whose box meets [qlo, qhi], or KDRT_INVALID_ID when there is none. */
static uint32_t kdrt__box_walk_next(kdrt__box_walk *w, const kdrt_tree *tree, const float qlo[3],
                                    const float qhi[3])
{
    int a;
    for (;;) {
        if (w->node == KDRT_INVALID_ID) {
            const kdrt__box_todo *top;
            if (w->sp == 0) return KDRT_INVALID_ID;
            top = &w->stack[--w->sp];
            w->node = top->node, w->faces = top->faces;
            for (a = 0; a < 3; ++a) w->lo[a] = top->lo[a], w->hi[a] = top->hi[a];
        }
        if (kdrt__boxes_meet(w->lo, w->hi, qlo, qhi)) {
            const kdrt__node *n = &tree->nodes[w->node];
            if (!kdrt__node_is_leaf(n)) {
                const uint32_t axis = kdrt__node_axis(n);
                kdrt__box_todo *above = &w->stack[w->sp++];
                KDRT_ASSERT(w->sp <= KDRT_MAX_DEPTH + 1);
                for (a = 0; a < 3; ++a) above->lo[a] = w->lo[a], above->hi[a] = w->hi[a];
                above->node = kdrt__node_above(n), above->lo[axis] = n->u.split;
                above->faces = w->faces | 1u << (2 * axis);
                w->hi[axis] = n->u.split, w->faces |= 1u << (2 * axis + 1), w->node += 1;
                continue;
            }
            {
                const uint32_t leaf = w->node;
                w->node = KDRT_INVALID_ID;
                return leaf;
            }
        }
        w->node = KDRT_INVALID_ID;
    }
}

/* Whether leaf, found by the walk of the box [qlo, qhi], is the one that reports triangle id whose
   box, cut by [qlo, qhi], is [blo, bhi] (and meets the leaf's box): the first leaf in node order
   (depth first, below first, as the nodes are numbered) whose box meets [blo, bhi] and that
   refers to id. Every leaf whose box meets [blo, bhi] is one the walk reaches, so exactly one of
   them says yes (CLOSEST POINT AND OVERLAP). */
static int kdrt__first_leaf_of(const kdrt_tree *tree, uint32_t leaf, uint32_t id,
                               const float blo[3], const float bhi[3])
{
    kdrt__box_walk walk;
    uint32_t node, i;
    kdrt__box_walk_start(&walk, tree);
    while ((node = kdrt__box_walk_next(&walk, tree, blo, bhi)) != KDRT_INVALID_ID) {
        const kdrt__node *n = &tree->nodes[node];
        if (node == leaf) return 1;
        for (i = 0; i < kdrt__node_count(n); ++i)
            if (tree->blocks[n->u.first + i / KDRT__LANES].id[i % KDRT__LANES] == id) return 0;
    }
    return 1; /* not reached: leaf itself meets the box */
}

/* One tree's walk of an overlap query: every leaf whose box meets [qlo, qhi] (the query's box
   in the tree's space, with room for the rounding of an instance's corners), and in it each
   triangle that meets the query's shape (its corners in the world) and for which this leaf is
   the one that reports it. geometry and instance name what is reported (a scene's mesh tree:
   geometry KDRT_INVALID_ID, each triangle named by its part). */
static void kdrt__overlap_walk(const kdrt_tree *tree, const kdrt__instance *in, const float qlo[3],
                               const float qhi[3], uint32_t geometry, kdrt__overlap_query *query)
{
    kdrt__box_walk walk;
    const float *lo = walk.lo, *hi = walk.hi;
    uint32_t node, i;
    const int check_mask = !tree->masks_full;
    int a;
    if (tree->stats.triangles == 0) return;
    kdrt__box_walk_start(&walk, tree);
    while ((node = kdrt__box_walk_next(&walk, tree, qlo, qhi)) != KDRT_INVALID_ID) {
        const kdrt__node *n = &tree->nodes[node];
        const uint32_t faces = walk.faces;
        for (i = 0; i < kdrt__node_count(n); ++i) {
            const kdrt__block *block = &tree->blocks[n->u.first + i / KDRT__LANES];
            const uint32_t id = block->id[i % KDRT__LANES];
            float object[3][3], world[3][3], blo[3], bhi[3];
            int inside = 1, k, meets;
            kdrt_overlap found;
            if (check_mask && !(kdrt__part_of(&tree->meshes, id)->mask & query->mask)) continue;
            kdrt__lane_world(block, i % KDRT__LANES, in, object, world);
            /* The triangle's box (in the tree's space) cut by the query's: the leaves whose
               boxes meet it are those that may report it. */
            for (a = 0; a < 3; ++a) {
                blo[a] = object[0][a], bhi[a] = object[0][a];
                for (k = 1; k < 3; ++k) {
                    blo[a] = object[k][a] < blo[a] ? object[k][a] : blo[a];
                    bhi[a] = object[k][a] > bhi[a] ? object[k][a] : bhi[a];
                }
                blo[a] = qlo[a] > blo[a] ? qlo[a] : blo[a];
                bhi[a] = qhi[a] < bhi[a] ? qhi[a] : bhi[a];
            }
            if (!kdrt__boxes_meet(blo, bhi, lo, hi)) continue;
            /* A ball's triangle also meets its box: the ball's test may take one within its
               error bound beyond the sphere, and only what meets the box is sure to be found
               in a leaf the walk reaches, whatever the tree (every tree reports what leaf size 0
               reports). */
            meets = (!query->sphere || !kdrt__finite(query->radius) ||
                     kdrt__triangle_ball(world, query->center, query->radius)) &&
                    kdrt__triangle_box(world, query->lo, query->hi);
            if (!meets) continue;
            /* Within the leaf's box, away from every split face: no other leaf's box meets
               it. Else the first leaf in node order that refers to it reports it. */
            for (a = 0; a < 3; ++a) {
                if ((faces >> (2 * a) & 1u) && !(blo[a] > lo[a])) inside = 0;
                if ((faces >> (2 * a + 1) & 1u) && !(bhi[a] < hi[a])) inside = 0;
            }
            if (!inside && !kdrt__first_leaf_of(tree, node, id, blo, bhi)) continue;
            found.triangle = id, found.geometry = geometry;
            found.instance = in ? in->id : KDRT_INVALID_ID;
            if (geometry == KDRT_INVALID_ID) {
                const kdrt__part *part = kdrt__part_of(&tree->meshes, id);
                found.triangle = id - part->first, found.geometry = part->id;
            }
            ++query->count;
            if (query->callback && !query->callback(query->user, &found)) {
                query->stopped = 1;
                return;
            }
        }
    }
}

/* The world box of the query: its box, or the ball's, rounded outwards. */
static kdrt_result kdrt__overlap_setup_box(const kdrt_aabb *box, kdrt__overlap_query *q, int *empty)
{
    int a;
    memset(q, 0, sizeof *q);
    *empty = 0;
    for (a = 0; a < 3; ++a)
        if (box->min[a] != box->min[a] || box->max[a] != box->max[a]) return KDRT_ERROR_INVALID_QUERY;
    for (a = 0; a < 3; ++a) {
        /* An infinite bound is a half-space: the triangles' corners are finite, so the largest
           float stands for it; min +inf or max -inf hold no finite point. */
        if (!(box->min[a] <= box->max[a]) || box->min[a] == INFINITY || box->max[a] == -INFINITY)
            *empty = 1;
        q->lo[a] = box->min[a] < -FLT_MAX ? -FLT_MAX : box->min[a];
        q->hi[a] = box->max[a] > FLT_MAX ? FLT_MAX : box->max[a];
    }
    q->mask = 0xFFFFFFFFu;
    return KDRT_SUCCESS;
}
static kdrt_result kdrt__overlap_setup_sphere(const float center[3], float radius,
                                              kdrt__overlap_query *q)
{
    int a;
    memset(q, 0, sizeof *q);
    if (!kdrt__finite(center[0]) || !kdrt__finite(center[1]) || !kdrt__finite(center[2]) ||
        !(radius >= 0.0f))
        return KDRT_ERROR_INVALID_QUERY;
    q->sphere = 1, q->radius = radius;
    for (a = 0; a < 3; ++a) {
        q->center[a] = center[a];
        q->lo[a] = kdrt__float_down((double)center[a] - radius);
        q->hi[a] = kdrt__float_up((double)center[a] + radius);
        q->lo[a] = q->lo[a] < -FLT_MAX ? -FLT_MAX : q->lo[a];
        q->hi[a] = q->hi[a] > FLT_MAX ? FLT_MAX : q->hi[a];
    }
    q->mask = 0xFFFFFFFFu;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_overlap_box(const kdrt_tree *tree, const kdrt_aabb *box,
                                      kdrt_overlap_fn callback, void *user, uint64_t *out_count)
{
    kdrt__overlap_query q;
    kdrt_result r;
    int empty;
    if (out_count) *out_count = 0;
    if (!tree || !box) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__overlap_setup_box(box, &q, &empty);
    if (r != KDRT_SUCCESS || empty) return r;
    q.callback = callback, q.user = user;
    kdrt__overlap_walk(tree, NULL, q.lo, q.hi, 0, &q);
    if (out_count) *out_count = q.count;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_overlap_sphere(const kdrt_tree *tree, const float center[3],
                                         float radius, kdrt_overlap_fn callback, void *user,
                                         uint64_t *out_count)
{
    kdrt__overlap_query q;
    kdrt_result r;
    if (out_count) *out_count = 0;
    if (!tree || !center) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__overlap_setup_sphere(center, radius, &q);
    if (r != KDRT_SUCCESS) return r;
    q.callback = callback, q.user = user;
    kdrt__overlap_walk(tree, NULL, q.lo, q.hi, 0, &q);
    if (out_count) *out_count = q.count;
    return KDRT_SUCCESS;
}

/* -- Scenes: the mesh tree, then the instances through the top level -- */

/* What a query carries into an instance's space: y = R^-1 (q - t), and how a distance there
   bounds one in the world (CLOSEST POINT AND OVERLAP): |R x| >= |x| / |R^-1|_F (the Frobenius
   norm bounds the largest singular value of R^-1), less the rounding of y and of the world
   corners. */
static void kdrt__instance_point(const kdrt__instance *in, const float q[3], double y[3],
                                 double *scale, double *slop)
{
    const double *r = in->to_object;
    double frob = 0.0, wfrob = 0.0, big = 0.0, rows = 0.0;
    int a, j;
    for (a = 0; a < 3; ++a) {
        const double x0 = (double)q[0] - in->to_world[3], x1 = (double)q[1] - in->to_world[7],
                     x2 = (double)q[2] - in->to_world[11];
        y[a] = r[3 * a] * x0 + r[3 * a + 1] * x1 + r[3 * a + 2] * x2;
    }
    for (a = 0; a < 9; ++a) frob += r[a] * r[a];
    for (a = 0; a < 3; ++a) {
        double row = 0.0;
        for (j = 0; j < 3; ++j) wfrob += in->to_world[4 * a + j] * in->to_world[4 * a + j];
        for (j = 0; j < 3; ++j) row += fabs(r[3 * a + j]);
        rows = row > rows ? row : rows;
        big = fabs((double)q[a]) + fabs(in->to_world[4 * a + 3]) > big
                  ? fabs((double)q[a]) + fabs(in->to_world[4 * a + 3]) : big;
    }
    frob = sqrt(frob);
    *scale = 1.0 / frob;
    /* y's rounding, at most 2^-50 |R^-1| (|q| + |t|) a component, is at most |R| times that in
       the world. */
    *slop = kdrt__instance_slop(in) +
            2.0 * sqrt(wfrob) * rows * big * 8.881784197001252e-16 /* 2^-50 */;
}

/* A lane of the top level waiting on a walk's stack, with its distance. */
typedef struct kdrt__level_near {
    uint32_t first, count;
    double distance;
} kdrt__level_near;

KDRT_API kdrt_result kdrt_scene_closest_point(const kdrt_scene *scene, const float point[3],
                                              float max_distance, uint32_t mask,
                                              kdrt_closest *out)
{
    kdrt__closest_best best;
    kdrt_result r;
    double y[3];
    if (!out) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__closest_start(scene, point, max_distance, out, &best);
    if (r != KDRT_SUCCESS || mask == 0) return r;
    y[0] = point[0], y[1] = point[1], y[2] = point[2];
    if (scene->meshes) {
        /* The mesh tree numbers its triangles in (geometry ID, triangle) order: the walk's ties
           go by that number, named afterwards. */
        kdrt__closest_walk(scene->meshes, NULL, y, point, 1.0, 0.0, mask, 0, &best);
        if (best.found) {
            const kdrt__part *part = kdrt__part_of(&scene->meshes->meshes, best.triangle);
            best.key = part->id, best.triangle -= part->first;
        }
    }
    if (scene->top.nodes) {
        const kdrt__level_node *nodes = scene->top.nodes;
        kdrt__level_near stack[KDRT__LEVEL_STACK];
        uint32_t sp = 0, node = 0, i;
        int done = 0;
        /* No margin for the reach of a far corner here (as the tree walk's): a triangle's error
           is 2^-44 of its far corner's distance, which is at most its own distance (covered by
           KDRT__PRUNE_SLACK) plus its instance's extent, and an instance's world box is widened
           by 2^-20 of its extent (kdrt__place_instance), far more than 2^-44 of it. */
        if (kdrt__box_distance(y, scene->top.root.min, scene->top.root.max) * KDRT__PRUNE_SLACK >
            best.distance)
            done = 1;
        while (!done) {
            const kdrt__level_node *n = &nodes[node];
            const uint32_t pushed = sp;
            unsigned c;
            for (c = 0; c < 4u; ++c) {
                float lo[3], hi[3];
                double d;
                uint32_t at;
                int a;
                if (n->count[c] == KDRT_INVALID_ID) continue;
                for (a = 0; a < 3; ++a) lo[a] = n->lo[a][c], hi[a] = n->hi[a][c];
                d = kdrt__box_distance(y, lo, hi);
                if (d * KDRT__PRUNE_SLACK > best.distance) continue;
                /* Farthest first on the stack: the nearest lane is popped next. */
                at = sp++;
                while (at > pushed && stack[at - 1u].distance < d) stack[at] = stack[at - 1u], --at;
                stack[at].first = n->first[c], stack[at].count = n->count[c], stack[at].distance = d;
            }
            for (;;) {
                kdrt__level_near e;
                if (sp == 0) {
                    done = 1;
                    break;
                }
                e = stack[--sp];
                if (e.distance * KDRT__PRUNE_SLACK > best.distance) continue;
                if (e.count == 0) {
                    node = e.first;
                    break;
                }
                for (i = 0; i < e.count; ++i) {
                    const kdrt__instance *in = &scene->now.instances[scene->top.items[e.first + i]];
                    double z[3], scale, slop;
                    if (!(in->mask & mask)) continue;
                    if (kdrt__box_distance(y, in->box.min, in->box.max) * KDRT__PRUNE_SLACK >
                        best.distance)
                        continue;
                    kdrt__instance_point(in, point, z, &scale, &slop);
                    kdrt__closest_walk(in->tree, in, z, point, scale, slop, 0xFFFFFFFFu, in->id,
                                       &best);
                }
            }
        }
    }
    kdrt__closest_finish(&best, out);
    return KDRT_SUCCESS;
}

/* The overlap query q on scene: the mesh tree, then each instance whose world box meets the
   query's, walked in its space with the query's box carried there (CLOSEST POINT AND OVERLAP). */
static void kdrt__scene_overlap(const kdrt_scene *scene, kdrt__overlap_query *q)
{
    const kdrt__level_node *nodes = scene->top.nodes;
    uint32_t stack[KDRT__LEVEL_STACK][2];
    uint32_t sp = 0, i;
    if (q->mask == 0) return;
    if (scene->meshes) kdrt__overlap_walk(scene->meshes, NULL, q->lo, q->hi, KDRT_INVALID_ID, q);
    if (q->stopped || !nodes || !kdrt__boxes_meet(scene->top.root.min, scene->top.root.max, q->lo, q->hi))
        return;
    stack[sp][0] = 0, stack[sp][1] = 0, ++sp;
    while (sp) {
        const uint32_t first = stack[sp - 1][0], count = stack[sp - 1][1];
        --sp;
        if (count == 0) {
            const kdrt__level_node *n = &nodes[first];
            unsigned c;
            for (c = 4u; c-- > 0u;) {
                float lo[3], hi[3];
                int a;
                if (n->count[c] == KDRT_INVALID_ID) continue;
                for (a = 0; a < 3; ++a) lo[a] = n->lo[a][c], hi[a] = n->hi[a][c];
                if (!kdrt__boxes_meet(lo, hi, q->lo, q->hi)) continue;
                KDRT_ASSERT(sp < KDRT__LEVEL_STACK);
                stack[sp][0] = n->first[c], stack[sp][1] = n->count[c], ++sp;
            }
            continue;
        }
        for (i = 0; i < count; ++i) {
            const kdrt__instance *in = &scene->now.instances[scene->top.items[first + i]];
            double lo[3], hi[3], slop, big = 0.0;
            float olo[3], ohi[3], wlo[3], whi[3];
            int a, k;
            if (!(in->mask & q->mask) || !kdrt__boxes_meet(in->box.min, in->box.max, q->lo, q->hi))
                continue;
            /* The query's box cut by the instance's, its corners carried into the tree's space,
               and their box widened by where R^-1 can take the rounding of the world corners
               (slop) and of this transform (2^-50 of the sums): no triangle the world box meets
               has all of its preimage outside. */
            for (a = 0; a < 3; ++a) {
                wlo[a] = q->lo[a] > in->box.min[a] ? q->lo[a] : in->box.min[a];
                whi[a] = q->hi[a] < in->box.max[a] ? q->hi[a] : in->box.max[a];
                lo[a] = INFINITY, hi[a] = -INFINITY;
            }
            slop = kdrt__instance_slop(in);
            for (k = 0; k < 8; ++k) {
                const double x0 = (double)(k & 1 ? whi[0] : wlo[0]) - in->to_world[3];
                const double x1 = (double)(k & 2 ? whi[1] : wlo[1]) - in->to_world[7];
                const double x2 = (double)(k & 4 ? whi[2] : wlo[2]) - in->to_world[11];
                for (a = 0; a < 3; ++a) {
                    const double *r = &in->to_object[3 * a];
                    const double y = r[0] * x0 + r[1] * x1 + r[2] * x2;
                    lo[a] = y < lo[a] ? y : lo[a], hi[a] = y > hi[a] ? y : hi[a];
                }
            }
            for (a = 0; a < 3; ++a) {
                const double t = fabs(in->to_world[4 * a + 3]);
                const double w = (fabs(wlo[a]) > fabs(whi[a]) ? fabs(wlo[a]) : fabs(whi[a])) + t;
                big = w > big ? w : big;
            }
            for (a = 0; a < 3; ++a) {
                const double *r = &in->to_object[3 * a];
                const double row = fabs(r[0]) + fabs(r[1]) + fabs(r[2]);
                const double pad = row * (slop + 2.0 * 8.881784197001252e-16 /* 2^-50 */ * big);
                olo[a] = kdrt__float_down(lo[a] - pad), ohi[a] = kdrt__float_up(hi[a] + pad);
            }
            kdrt__overlap_walk(in->tree, in, olo, ohi, in->id, q);
            if (q->stopped) return;
        }
    }
}

KDRT_API kdrt_result kdrt_scene_overlap_box(const kdrt_scene *scene, const kdrt_aabb *box,
                                            uint32_t mask, kdrt_overlap_fn callback, void *user,
                                            uint64_t *out_count)
{
    kdrt__overlap_query q;
    kdrt_result r;
    int empty;
    if (out_count) *out_count = 0;
    if (!scene || !box) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__overlap_setup_box(box, &q, &empty);
    if (r != KDRT_SUCCESS || empty) return r;
    q.callback = callback, q.user = user, q.mask = mask;
    kdrt__scene_overlap(scene, &q);
    if (out_count) *out_count = q.count;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_scene_overlap_sphere(const kdrt_scene *scene, const float center[3],
                                               float radius, uint32_t mask,
                                               kdrt_overlap_fn callback, void *user,
                                               uint64_t *out_count)
{
    kdrt__overlap_query q;
    kdrt_result r;
    if (out_count) *out_count = 0;
    if (!scene || !center) return KDRT_ERROR_NULL_ARGUMENT;
    r = kdrt__overlap_setup_sphere(center, radius, &q);
    if (r != KDRT_SUCCESS) return r;
    q.callback = callback, q.user = user, q.mask = mask;
    kdrt__scene_overlap(scene, &q);
    if (out_count) *out_count = q.count;
    return KDRT_SUCCESS;
}

/* ==== optics: reflection, refraction, Fresnel reflectance ==== */

static int kdrt__finite_positive(float x) { return x > 0.0f && kdrt__finite(x); }

/* v in double; 0 when a component is NaN or infinite or all three are zero. */
static int kdrt__load_direction(const float v[3], double d[3])
{
    d[0] = v[0], d[1] = v[1], d[2] = v[2];
    return kdrt__finite(v[0]) && kdrt__finite(v[1]) && kdrt__finite(v[2]) &&
           (v[0] != 0.0f || v[1] != 0.0f || v[2] != 0.0f);
}

static double kdrt__dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* cos^2 of the transmitted angle, 1 - eta^2 (1 - cos_i^2), for the Fresnel functions' float
   cosine; negative on total internal reflection. A float eta and a float cosine square exactly
   in double, and 1 - eta^2 is exact for 1 <= eta < 2^23 (below 1 there is no total internal
   reflection to decide), so with one fma the sign is exact. */
static double kdrt__cos2_t(double eta, double cos_i)
{
    return fma(eta * eta, cos_i * cos_i, 1.0 - eta * eta);
}

/* The unit mirror direction of i about the plane with normal n, from d = i.n, li = |i|,
   nn = |n|^2. The double intermediates cannot overflow, and the float result is a unit vector. */
static void kdrt__mirror(const double i[3], const double n[3], double d, double li, double nn,
                         float out[3])
{
    double s = 2.0 * d / nn;
    int a;
    for (a = 0; a < 3; ++a) out[a] = (float)((i[a] - s * n[a]) / li);
}

KDRT_API void kdrt_reflect(const float incident[3], const float normal[3], float out[3])
{
    double i[3], n[3];
    int a;
    if (!incident || !normal || !out) return;
    if (!kdrt__load_direction(incident, i) || !kdrt__load_direction(normal, n)) {
        for (a = 0; a < 3; ++a) out[a] = incident[a];
        return;
    }
    kdrt__mirror(i, n, kdrt__dot(i, n), sqrt(kdrt__dot(i, i)), kdrt__dot(n, n), out);
}

KDRT_API int kdrt_refract(const float incident[3], const float normal[3], float eta, float out[3])
{
    double i[3], n[3], w[3], t[3], d, ii, nn, li, k, e = eta;
    int a;
    if (!incident || !normal || !out) return -1;
    if (!kdrt__load_direction(incident, i) || !kdrt__load_direction(normal, n) ||
        !kdrt__finite_positive(eta)) {
        for (a = 0; a < 3; ++a) out[a] = incident[a];
        return -1;
    }
    d = kdrt__dot(i, n), ii = kdrt__dot(i, i), nn = kdrt__dot(n, n), li = sqrt(ii);
    if (d > 0.0) { /* make the normal face the side the light comes from */
        for (a = 0; a < 3; ++a) n[a] = -n[a];
        d = -d;
    }
    /* w = n x i, |w| = |n| |i| sin(theta_i). Each component is one rounding of a difference of
       exact products, so w is accurate even for nearly parallel i and n. k = |i|^2 |n|^2
       cos^2(theta_t) = |i|^2 |n|^2 - eta^2 |w|^2, rounded once: negative is total internal
       reflection, and an exactly critical angle with exact inputs gives exactly 0. */
    kdrt__cross(n, i, w);
    k = fma(-e * e, kdrt__dot(w, w), ii * nn);
    if (k < 0.0) {
        kdrt__mirror(i, n, d, li, nn, out);
        return 0;
    }
    /* Snell: the tangential part of the unit incident direction, (w x n) / (|i| |n|^2), scaled by
       eta, plus the normal part -cos_t n / |n|. w x n is accurate to about a double ulp of its
       length, |i| |n|^2 sin(theta_i), and eta sin(theta_i) <= 1 here, so even a huge eta keeps the
       result a unit vector. */
    kdrt__cross(w, n, t);
    for (a = 0; a < 3; ++a) out[a] = (float)(e * t[a] / (li * nn) - sqrt(k) / (li * nn) * n[a]);
    return 1;
}

/* s and p reflectances; both 0 for invalid input and for eta = 1, both 1 on total internal
   reflection. */
static void kdrt__fresnel(float cos_i, float eta, double *rs, double *rp)
{
    double c = fabs((double)cos_i), e = eta, k, cos_t, s, p;
    *rs = *rp = 0.0;
    if (cos_i != cos_i || !kdrt__finite_positive(eta) || eta == 1.0f) return;
    if (c > 1.0) c = 1.0;
    k = kdrt__cos2_t(e, c);
    if (k < 0.0) {
        *rs = *rp = 1.0;
        return;
    }
    /* The denominators are 0 only for c = cos_t = 0, which needs eta = 1. */
    cos_t = sqrt(k);
    s = (e * c - cos_t) / (e * c + cos_t);
    p = (c - e * cos_t) / (c + e * cos_t);
    *rs = s * s, *rp = p * p;
}

KDRT_API float kdrt_fresnel_dielectric(float cos_i, float eta)
{
    double rs, rp;
    kdrt__fresnel(cos_i, eta, &rs, &rp);
    return (float)(0.5 * (rs + rp));
}

KDRT_API void kdrt_fresnel_dielectric_sp(float cos_i, float eta, float *rs, float *rp)
{
    double s, p;
    kdrt__fresnel(cos_i, eta, &s, &p);
    if (rs) *rs = (float)s;
    if (rp) *rp = (float)p;
}

KDRT_API float kdrt_fresnel_schlick(float cos_i, float eta)
{
    double c = fabs((double)cos_i), e = eta, r0 = (e - 1.0) / (e + 1.0), m;
    if (cos_i != cos_i || !kdrt__finite_positive(eta) || eta == 1.0f) return 0.0f;
    if (c > 1.0) c = 1.0;
    if (e > 1.0) { /* Schlick's formula takes the angle on the less dense side */
        double k = kdrt__cos2_t(e, c);
        if (k < 0.0) return 1.0f;
        c = sqrt(k);
    }
    r0 *= r0, m = 1.0 - c;
    return (float)(r0 + (1.0 - r0) * m * m * m * m * m);
}

/* ==== media stack ==== */

typedef char kdrt__media_stack_has_room[KDRT_MEDIA_STACK_CAPACITY >= 1 ? 1 : -1];

/* Entries to read: count, but never past the array, whatever the caller wrote into count. */
static uint32_t kdrt__media_count(const kdrt_media_stack *s)
{
    return s->count < KDRT_MEDIA_STACK_CAPACITY ? s->count : KDRT_MEDIA_STACK_CAPACITY;
}

/* Index of the current medium, the highest priority and latest entered, leaving out entry skip;
   KDRT_INVALID_ID for the outside medium. */
static uint32_t kdrt__media_current(const kdrt_media_stack *s, uint32_t skip)
{
    uint32_t i, best = KDRT_INVALID_ID, n = kdrt__media_count(s);
    for (i = 0; i < n; ++i)
        if (i != skip &&
            (best == KDRT_INVALID_ID || s->media[i].priority >= s->media[best].priority))
            best = i;
    return best;
}

static float kdrt__media_ior(const kdrt_media_stack *s, uint32_t entry)
{
    return entry == KDRT_INVALID_ID ? s->outside_ior : s->media[entry].ior;
}

/* Index of object's latest entry, or KDRT_INVALID_ID. */
static uint32_t kdrt__media_find(const kdrt_media_stack *s, uint32_t object)
{
    uint32_t i = kdrt__media_count(s);
    while (i-- > 0)
        if (s->media[i].object == object) return i;
    return KDRT_INVALID_ID;
}

KDRT_API kdrt_result kdrt_media_init(kdrt_media_stack *stack, float outside_ior)
{
    if (!stack) return KDRT_ERROR_NULL_ARGUMENT;
    memset(stack, 0, sizeof *stack);
    stack->outside_ior = kdrt__finite_positive(outside_ior) ? outside_ior : 1.0f;
    return kdrt__finite_positive(outside_ior) ? KDRT_SUCCESS : KDRT_ERROR_INVALID_IOR;
}

KDRT_API float kdrt_media_current_ior(const kdrt_media_stack *stack)
{
    return stack ? kdrt__media_ior(stack, kdrt__media_current(stack, KDRT_INVALID_ID)) : 1.0f;
}

KDRT_API uint32_t kdrt_media_current_object(const kdrt_media_stack *stack)
{
    uint32_t entry = stack ? kdrt__media_current(stack, KDRT_INVALID_ID) : KDRT_INVALID_ID;
    return entry == KDRT_INVALID_ID ? KDRT_INVALID_ID : stack->media[entry].object;
}

KDRT_API int kdrt_media_contains(const kdrt_media_stack *stack, uint32_t object)
{
    return stack && kdrt__media_find(stack, object) != KDRT_INVALID_ID;
}

KDRT_API kdrt_result kdrt_media_enter(kdrt_media_stack *stack, uint32_t object, float ior,
                                      int priority)
{
    kdrt_medium *m;
    if (!stack) return KDRT_ERROR_NULL_ARGUMENT;
    if (!kdrt__finite_positive(ior)) return KDRT_ERROR_INVALID_IOR;
    if (stack->count >= KDRT_MEDIA_STACK_CAPACITY) return KDRT_ERROR_MEDIA_STACK_FULL;
    m = &stack->media[stack->count++];
    m->object = object, m->ior = ior, m->priority = priority;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_result kdrt_media_leave(kdrt_media_stack *stack, uint32_t object)
{
    uint32_t i, n;
    if (!stack) return KDRT_ERROR_NULL_ARGUMENT;
    i = kdrt__media_find(stack, object), n = kdrt__media_count(stack);
    if (i == KDRT_INVALID_ID) return KDRT_ERROR_NOT_IN_MEDIUM;
    for (; i + 1 < n; ++i) stack->media[i] = stack->media[i + 1];
    stack->count = n - 1;
    return KDRT_SUCCESS;
}

KDRT_API kdrt_media_crossing kdrt_media_at_surface(const kdrt_media_stack *stack, uint32_t object,
                                                   float ior, int priority)
{
    kdrt_media_stack empty;
    kdrt_media_crossing x;
    uint32_t current, entry;
    if (!stack) kdrt_media_init(&empty, 1.0f), stack = &empty;
    current = kdrt__media_current(stack, KDRT_INVALID_ID);
    entry = kdrt__media_find(stack, object);
    x.entering = entry == KDRT_INVALID_ID;
    x.eta_incident = kdrt__media_ior(stack, current);
    if (x.entering) /* the object becomes current unless a higher priority medium holds the ray */
        x.real = current == KDRT_INVALID_ID || priority >= stack->media[current].priority;
    else /* leaving: only the current medium's surface changes anything */
        x.real = entry == current;
    if (!x.real)
        x.eta_transmitted = x.eta_incident;
    else
        x.eta_transmitted =
            x.entering ? ior : kdrt__media_ior(stack, kdrt__media_current(stack, entry));
    return x;
}

#if defined(KDRT__AVX2) && defined(_MSC_VER) && !defined(__clang__)
#pragma warning(pop) /* C4752, pushed where the AVX2 target attribute is defined */
#endif

#ifdef __cplusplus
}
#endif
#if defined(__clang__)
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wignored-pragmas"
#pragma float_control(pop)
#pragma clang diagnostic pop
#elif defined(__GNUC__)
#pragma GCC pop_options
#endif
#endif /* KDRT_IMPLEMENTATION */

/* ==== packets: the code written once over the vector width ==== */

/* The lanes' exact test and the packet walk, for 8 lanes (the AVX2 kernel: its block tests and
   its 8-ray packets) and for 16 (the AVX-512 kernel's 16-ray packets). C has no templates, so,
   as stb_image_resize2.h does for its loops, kdrt.h includes itself (KDRT_HEADER_FILENAME) with
   KDRT__PACKET_WIDTH set, and this part alone is compiled again: each name through KDRT__W()
   ends in _avx2 or _avx512, each vector operation is a kdrt__v_ macro of that width. Parts
   (KDRT__PACKET_PARTS): 1 the lanes' test, 2 the packets. */
#if defined(KDRT__PACKET_WIDTH)

#if KDRT__PACKET_WIDTH == 8
#define KDRT__W(name) name##_avx2
#define KDRT__W_TARGET KDRT__TARGET_AVX2
#define kdrt__v __m256                 /* W floats */
#define kdrt__vm __m256                /* W lanes' truth: all bits set or clear */
#define kdrt__vd __m256d               /* W / 2 doubles */
#define kdrt__vdm __m256d
#define kdrt__v_set1(x) _mm256_set1_ps(x)
#define kdrt__v_zero() _mm256_setzero_ps()
#define kdrt__v_load(p) _mm256_loadu_ps(p)
#define kdrt__v_store(p, x) _mm256_storeu_ps(p, x)
#define kdrt__v_add(a, b) _mm256_add_ps(a, b)
#define kdrt__v_sub(a, b) _mm256_sub_ps(a, b)
#define kdrt__v_mul(a, b) _mm256_mul_ps(a, b)
#define kdrt__v_div(a, b) _mm256_div_ps(a, b)
#define kdrt__v_abs(a) _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a)
#define kdrt__v_cmp(a, b, predicate) _mm256_cmp_ps(a, b, predicate)
#define kdrt__v_blend(a, b, m) _mm256_blendv_ps(a, b, m) /* b where m, else a */
#define kdrt__v_gather(base, index) _mm256_i32gather_ps(base, index, 4)
#define kdrt__m_gather_zero(base, index)                                                        \
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_i32gather_epi32((const int *)(base), index, 4), \
                                           _mm256_setzero_si256()))
#define kdrt__m_and(a, b) _mm256_and_ps(a, b)
#define kdrt__m_or(a, b) _mm256_or_ps(a, b)
#define kdrt__m_xor(a, b) _mm256_xor_ps(a, b)
#define kdrt__m_andnot(a, b) _mm256_andnot_ps(a, b) /* b and not a */
#define kdrt__m_all() _mm256_castsi256_ps(_mm256_set1_epi32(-1))
#define kdrt__m_none() _mm256_setzero_ps()
#define kdrt__m_bits(m) ((unsigned)_mm256_movemask_ps(m))
#define kdrt__vd_zero() _mm256_setzero_pd()
#define kdrt__vd_set1(x) _mm256_set1_pd(x)
#define kdrt__vd_add(a, b) _mm256_add_pd(a, b)
#define kdrt__vd_sub(a, b) _mm256_sub_pd(a, b)
#define kdrt__vd_mul(a, b) _mm256_mul_pd(a, b)
#define kdrt__vd_div(a, b) _mm256_div_pd(a, b)
#define kdrt__vd_cmp(a, b, predicate) _mm256_cmp_pd(a, b, predicate)
#define kdrt__md_and(a, b) _mm256_and_pd(a, b)
#define kdrt__md_or(a, b) _mm256_or_pd(a, b)
#define kdrt__md_andnot(a, b) _mm256_andnot_pd(a, b)
#define kdrt__md_bits(m) ((unsigned)_mm256_movemask_pd(m))
#define kdrt__vd_widen(x, half) /* the floats of half 0 or 1 of x, exact */                  \
    _mm256_cvtps_pd((half) ? _mm256_extractf128_ps(x, 1) : _mm256_castps256_ps128(x))
#define kdrt__vd_store_ps(p, x) _mm_storeu_ps(p, _mm256_cvtpd_ps(x))
/* Lane i of a ray's floats: rays are 9 floats apart. */
#define kdrt__vi_ray_index() _mm256_setr_epi32(0, 9, 18, 27, 36, 45, 54, 63)


#elif KDRT__PACKET_WIDTH == 16
#define KDRT__W(name) name##_avx512
#define KDRT__W_TARGET KDRT__TARGET_AVX512
#define kdrt__v __m512
#define kdrt__vm __mmask16
#define kdrt__vd __m512d
#define kdrt__vdm __mmask8
#if defined(__FMA__)
/* The whole file is compiled with FMA: the compiler may fuse these as it fuses the AVX2
   kernel's operations of the same shape. */
#define kdrt__v_add(a, b) _mm512_add_ps(a, b)
#define kdrt__v_sub(a, b) _mm512_sub_ps(a, b)
#define kdrt__v_mul(a, b) _mm512_mul_ps(a, b)
#define kdrt__vd_add(a, b) _mm512_add_pd(a, b)
#define kdrt__vd_sub(a, b) _mm512_sub_pd(a, b)
#define kdrt__vd_mul(a, b) _mm512_mul_pd(a, b)
#else
/* AVX-512 implies FMA, and GCC fuses a multiply and an add of plain intrinsics into one (its
   default -ffp-contract=fast), which the AVX2 kernel's code, without FMA, never does: the forms
   with the rounding named are not fused, so each operation rounds as the AVX2 kernel's does
   (their zero-masking forms with every lane kept: GCC 12's unmasked intrinsics start from an
   undefined vector, which trips its -Wmaybe-uninitialized in C++; so below too). */
#define KDRT__NEAREST (_MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC)
#define kdrt__v_add(a, b) _mm512_maskz_add_round_ps(0xFFFF, a, b, KDRT__NEAREST)
#define kdrt__v_sub(a, b) _mm512_maskz_sub_round_ps(0xFFFF, a, b, KDRT__NEAREST)
#define kdrt__v_mul(a, b) _mm512_maskz_mul_round_ps(0xFFFF, a, b, KDRT__NEAREST)
#define kdrt__vd_add(a, b) _mm512_maskz_add_round_pd(0xFF, a, b, KDRT__NEAREST)
#define kdrt__vd_sub(a, b) _mm512_maskz_sub_round_pd(0xFF, a, b, KDRT__NEAREST)
#define kdrt__vd_mul(a, b) _mm512_maskz_mul_round_pd(0xFF, a, b, KDRT__NEAREST)
#endif
#define kdrt__v_set1(x) _mm512_set1_ps(x)
#define kdrt__v_zero() _mm512_setzero_ps()
#define kdrt__v_load(p) _mm512_loadu_ps(p)
#define kdrt__v_store(p, x) _mm512_storeu_ps(p, x)
#define kdrt__v_div(a, b) _mm512_div_ps(a, b)
#define kdrt__v_abs(a) _mm512_abs_ps(a)
#define kdrt__v_cmp(a, b, predicate) _mm512_cmp_ps_mask(a, b, predicate)
#define kdrt__v_blend(a, b, m) _mm512_mask_blend_ps(m, a, b)
#define kdrt__v_gather(base, index)                                                             \
    _mm512_mask_i32gather_ps(_mm512_setzero_ps(), 0xFFFF, index, base, 4)
#define kdrt__m_gather_zero(base, index)                                                        \
    _mm512_cmpeq_epi32_mask(                                                                    \
        _mm512_mask_i32gather_epi32(_mm512_setzero_si512(), 0xFFFF, index, (const int *)(base), 4), \
        _mm512_setzero_si512())
#define kdrt__m_and(a, b) ((__mmask16)((a) & (b)))
#define kdrt__m_or(a, b) ((__mmask16)((a) | (b)))
#define kdrt__m_xor(a, b) ((__mmask16)((a) ^ (b)))
#define kdrt__m_andnot(a, b) ((__mmask16)(~(a) & (b)))
#define kdrt__m_all() ((__mmask16)0xFFFFu)
#define kdrt__m_none() ((__mmask16)0)
#define kdrt__m_bits(m) ((unsigned)(m))
#define kdrt__vd_zero() _mm512_setzero_pd()
#define kdrt__vd_set1(x) _mm512_set1_pd(x)
#define kdrt__vd_div(a, b) _mm512_div_pd(a, b)
#define kdrt__vd_cmp(a, b, predicate) _mm512_cmp_pd_mask(a, b, predicate)
#define kdrt__md_and(a, b) ((__mmask8)((a) & (b)))
#define kdrt__md_or(a, b) ((__mmask8)((a) | (b)))
#define kdrt__md_andnot(a, b) ((__mmask8)(~(a) & (b)))
#define kdrt__md_bits(m) ((unsigned)(m))
#define kdrt__vd_half(x, half) _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(0xF, _mm512_castps_pd(x), half))
#define kdrt__vd_widen(x, half) _mm512_maskz_cvtps_pd(0xFF, (half) ? kdrt__vd_half(x, 1) : kdrt__vd_half(x, 0))
#define kdrt__vd_store_ps(p, x) _mm256_storeu_ps(p, _mm512_maskz_cvtpd_ps(0xFF, x))
#define kdrt__vi_ray_index()                                                                    \
    _mm512_setr_epi32(0, 9, 18, 27, 36, 45, 54, 63, 72, 81, 90, 99, 108, 117, 126, 135)

#endif

#if KDRT__PACKET_PARTS & 1
/* ---- the lanes' exact test ---- */

/* A filter in float before the exact edge functions: the lanes that surely have edge functions
   of both signs, so that the exact test would reject them. An edge function a * b - c * d
   is negative where a * b < c * d; rounding is monotone, so where float's products compare
   a * b < c * d (or >), the exact ones do too. Equal float products (or a NaN from an overflow)
   say nothing, and the exact test decides. The products are compared, not subtracted: a
   compiler may fuse a * b - (c * d) into an FMA (-mfma -ffp-contract=fast), whose sign can be
   wrong. So the filter changes no answer, only how soon most blocks are left. */
KDRT__W_TARGET static KDRT__FORCEINLINE unsigned KDRT__W(kdrt__surely_missed)(const kdrt__v x[3],
                                                                              const kdrt__v y[3])
{
    kdrt__vm neg = kdrt__m_none(), pos = kdrt__m_none();
    int k;
    for (k = 0; k < 3; ++k) {
        const int i = (k + 2) % 3, j = (k + 1) % 3; /* edge j-i, weight of corner k, as below */
        const kdrt__v a = kdrt__v_mul(x[i], y[j]), b = kdrt__v_mul(y[i], x[j]);
        neg = kdrt__m_or(neg, kdrt__v_cmp(a, b, _CMP_LT_OQ));
        pos = kdrt__m_or(pos, kdrt__v_cmp(a, b, _CMP_GT_OQ));
    }
    return kdrt__m_bits(kdrt__m_and(neg, pos));
}

/* The exact part of kdrt__intersect_watertight on W lanes of corners already moved to the ray's
   origin and sheared (x, y, z: corner k's in each lane), for the lanes of lanes. A lane is a
   triangle of a block against one ray (kdrt__block_watertight_avx2), or a triangle against a
   ray of a packet (kdrt__packet_leaf): the same arithmetic either way, in double, half the lanes
   at a time. */
KDRT__W_TARGET static KDRT__FORCEINLINE unsigned KDRT__W(kdrt__watertight_lanes)(
    const kdrt__v fx[3], const kdrt__v fy[3], const kdrt__v fz[3], unsigned lanes,
    kdrt__candidates *c)
{
    const kdrt__vd zero = kdrt__vd_zero();
    const unsigned half = KDRT__PACKET_WIDTH / 2;
    kdrt__vd x[3][2], y[3][2], z[3][2], e0[2], e1[2], e2[2], det[2];
    unsigned mask = 0;
    int k, h;
    if ((KDRT__W(kdrt__surely_missed)(fx, fy) | ~lanes) == 0xFFFFFFFFu) return 0;
    for (k = 0; k < 3; ++k)
        for (h = 0; h < 2; ++h)
            x[k][h] = kdrt__vd_widen(fx[k], h), y[k][h] = kdrt__vd_widen(fy[k], h),
            z[k][h] = kdrt__vd_widen(fz[k], h);
    for (h = 0; h < 2; ++h) {
        kdrt__vdm neg, pos, keep;
        e0[h] = kdrt__vd_sub(kdrt__vd_mul(x[2][h], y[1][h]), kdrt__vd_mul(y[2][h], x[1][h]));
        e1[h] = kdrt__vd_sub(kdrt__vd_mul(x[0][h], y[2][h]), kdrt__vd_mul(y[0][h], x[2][h]));
        e2[h] = kdrt__vd_sub(kdrt__vd_mul(x[1][h], y[0][h]), kdrt__vd_mul(y[1][h], x[0][h]));
        neg = kdrt__md_or(kdrt__md_or(kdrt__vd_cmp(e0[h], zero, _CMP_LT_OQ),
                                      kdrt__vd_cmp(e1[h], zero, _CMP_LT_OQ)),
                          kdrt__vd_cmp(e2[h], zero, _CMP_LT_OQ));
        pos = kdrt__md_or(kdrt__md_or(kdrt__vd_cmp(e0[h], zero, _CMP_GT_OQ),
                                      kdrt__vd_cmp(e1[h], zero, _CMP_GT_OQ)),
                          kdrt__vd_cmp(e2[h], zero, _CMP_GT_OQ));
        det[h] = kdrt__vd_add(kdrt__vd_add(e0[h], e1[h]), e2[h]);
        /* not (negative and positive), and det != 0 (unordered: NaN goes on, as in C) */
        keep = kdrt__md_andnot(kdrt__md_and(neg, pos), kdrt__vd_cmp(det[h], zero, _CMP_NEQ_UQ));
        mask |= kdrt__md_bits(keep) << (half * (unsigned)h);
    }
    mask &= lanes;
    if (!mask) return 0; /* most blocks: no lane's triangle contains the ray */
    c->front = 0;
    for (h = 0; h < 2; ++h) {
        const kdrt__vd inv_det = kdrt__vd_div(kdrt__vd_set1(1.0), det[h]);
        const kdrt__vd num = kdrt__vd_add(kdrt__vd_add(kdrt__vd_mul(e0[h], z[0][h]),
                                                       kdrt__vd_mul(e1[h], z[1][h])),
                                          kdrt__vd_mul(e2[h], z[2][h]));
        c->front |= kdrt__md_bits(kdrt__vd_cmp(det[h], zero, _CMP_GT_OQ)) << (half * (unsigned)h);
        kdrt__vd_store_ps(c->t + half * (unsigned)h, kdrt__vd_mul(num, inv_det));
        kdrt__vd_store_ps(c->u + half * (unsigned)h, kdrt__vd_mul(e1[h], inv_det));
        kdrt__vd_store_ps(c->v + half * (unsigned)h, kdrt__vd_mul(e2[h], inv_det));
    }
    return mask;
}
#endif /* KDRT__PACKET_PARTS & 1 */

#if KDRT__PACKET_PARTS & 2
/* ---- the packets ---- */

#if KDRT__PACKET_WIDTH == 8
/* The least and the greatest of x over the lanes of lanes (one at least). */
KDRT__W_TARGET static KDRT__FORCEINLINE void kdrt__v_range_avx2(__m256 x, unsigned lanes,
                                                                float *least, float *greatest)
{
    const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256 in = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32((int)lanes), bit), bit));
    __m256 lo = _mm256_blendv_ps(_mm256_set1_ps(INFINITY), x, in);
    __m256 hi = _mm256_blendv_ps(_mm256_set1_ps(-INFINITY), x, in);
    lo = _mm256_min_ps(lo, _mm256_permute2f128_ps(lo, lo, 1));
    hi = _mm256_max_ps(hi, _mm256_permute2f128_ps(hi, hi, 1));
    lo = _mm256_min_ps(lo, _mm256_shuffle_ps(lo, lo, 0x4E));
    hi = _mm256_max_ps(hi, _mm256_shuffle_ps(hi, hi, 0x4E));
    lo = _mm256_min_ps(lo, _mm256_shuffle_ps(lo, lo, 0xB1));
    hi = _mm256_max_ps(hi, _mm256_shuffle_ps(hi, hi, 0xB1));
    *least = _mm256_cvtss_f32(lo), *greatest = _mm256_cvtss_f32(hi);
}
#define kdrt__v_range kdrt__v_range_avx2
#else
/* The least and the greatest of x over the lanes of lanes (one at least). */
KDRT__W_TARGET static KDRT__FORCEINLINE void kdrt__v_range_avx512(__m512 x, unsigned lanes,
                                                                  float *least, float *greatest)
{
    /* the halves' least and greatest, then kdrt__v_range_avx2's reduction (GCC 12's
       _mm512_mask_reduce_min_ps trips -Wmaybe-uninitialized in C++) */
    const __m512 lo = _mm512_mask_blend_ps((__mmask16)lanes, _mm512_set1_ps(INFINITY), x);
    const __m512 hi = _mm512_mask_blend_ps((__mmask16)lanes, _mm512_set1_ps(-INFINITY), x);
    float unused;
    kdrt__v_range_avx2(_mm256_min_ps(kdrt__vd_half(lo, 0), kdrt__vd_half(lo, 1)), 0xFFu, least, &unused);
    kdrt__v_range_avx2(_mm256_max_ps(kdrt__vd_half(hi, 0), kdrt__vd_half(hi, 1)), 0xFFu, &unused, greatest);
}
#define kdrt__v_range kdrt__v_range_avx512
#endif

/* A node for later, with the lanes that visit it and their ranges there. Floats, not vectors:
   a vector's alignment would pad each entry to 192 bytes (AVX-512), and the walk's stack is the
   most of a batch call's stack. */
typedef struct KDRT__W(kdrt__packet_todo) {
    float t0[KDRT__PACKET_WIDTH], t1[KDRT__PACKET_WIDTH];
    uint32_t node;
    unsigned lanes;
} KDRT__W(kdrt__packet_todo);

/* One leaf for the lanes of lanes of a sheared packet (kdrt__packet.sheared): the triangles no
   cull rules out, each against the lanes' rays at once, with kdrt__intersect_watertight's
   arithmetic in each lane; each lane's hits taken as its own walk takes them. Returns the lanes
   that found one when any_hit. */
KDRT__W_TARGET static unsigned KDRT__W(kdrt__packet_leaf)(const kdrt_tree *tree,
                                                          const kdrt__node *n, kdrt__packet *p,
                                                          unsigned lanes, int any_hit,
                                                          kdrt_traversal_stats *stats)
{
    const uint32_t first = n->u.first, count = kdrt__node_count(n);
    const int kx = p->kx, ky = p->ky, kz = p->kz;
    const kdrt__v ox = kdrt__v_load(p->org[kx]), oy = kdrt__v_load(p->org[ky]);
    const kdrt__v oz = kdrt__v_load(p->org[kz]);
    const kdrt__v sx = kdrt__v_load(p->shear[0]), sy = kdrt__v_load(p->shear[1]);
    const kdrt__v sz = kdrt__v_load(p->shear[2]);
    unsigned found = 0;
    uint32_t i;
    for (i = 0; i < count; i += KDRT__LANES) {
        const kdrt__block *block = &tree->blocks[first + i / KDRT__LANES];
        /* the block's own triangles: a last block's copies of its last one repeat its answer */
        unsigned triangles = count - i < KDRT__LANES ? (1u << (count - i)) - 1u : 0xFFu;
        triangles &= ~(p->point ? kdrt__packet_culled_avx2(block, p, 1) : kdrt__packet_culled_avx2(block, p, 0));
        KDRT__COUNT(stats, packet_blocks, 1);
        if (kdrt__bit_count(triangles) > kdrt__bit_count(lanes)) {
            /* More triangles left than rays: each ray's test of the block costs less. */
            unsigned left;
            for (left = lanes; left; left &= left - 1u) {
                const unsigned lane = kdrt__ctz(left);
                kdrt__candidates c;
                const unsigned mask = kdrt__block_test_apart(block, &p->s[lane], &c);
                KDRT__COUNT(stats, block_tests, 1);
                if (!mask || !kdrt__accept_lanes(p->best[lane], block, mask, &c, &p->s[lane], 0))
                    continue;
                p->bound[lane] = p->best[lane]->t;
                if (any_hit) found |= 1u << lane, lanes &= ~(1u << lane);
            }
            if (!lanes) return found;
            continue;
        }
        for (; triangles; triangles &= triangles - 1u) {
            const unsigned j = kdrt__ctz(triangles), id = block->id[j];
            kdrt__v fx[3], fy[3], fz[3];
            kdrt__candidates c;
            unsigned hits;
            int k;
            KDRT__COUNT(stats, packet_triangles, 1);
            for (k = 0; k < 3; ++k) {
                const kdrt__v dx = kdrt__v_sub(kdrt__v_set1(block->corner[3 * k + kx][j]), ox);
                const kdrt__v dy = kdrt__v_sub(kdrt__v_set1(block->corner[3 * k + ky][j]), oy);
                const kdrt__v dz = kdrt__v_sub(kdrt__v_set1(block->corner[3 * k + kz][j]), oz);
                fx[k] = kdrt__v_sub(dx, kdrt__v_mul(sx, dz));
                fy[k] = kdrt__v_sub(dy, kdrt__v_mul(sy, dz));
                fz[k] = kdrt__v_mul(sz, dz);
            }
            for (hits = KDRT__W(kdrt__watertight_lanes)(fx, fy, fz, lanes, &c); hits; hits &= hits - 1u) {
                const unsigned lane = kdrt__ctz(hits);
                kdrt_hit *best = p->best[lane];
                if (!kdrt__accept(best, id, c.t[lane], c.u[lane], c.v[lane], &p->s[lane])) continue;
                p->bound[lane] = best->t;
                if (any_hit) found |= 1u << lane, lanes &= ~(1u << lane);
            }
            if (!lanes) return found;
        }
    }
    return found;
}

/* The packet's walk from the root: kdrt__walk_ray's walk from the root for each lane, the lanes
   that visit the same node at once. At a plane each lane takes kdrt__descend's decision, with its
   operations, so the same one: near only, far only, both (near, the first, up to the plane, far
   from it), or the origin on the plane (far, then the first, up to t = 0, near over the whole
   range). The children are visited in the packet's order, the side the rays come from first; a
   lane whose origin lies off the plane at a distance that rounds to t = 0 would visit them the
   other way round: it goes back to the single-ray walk. Inlined twice, so that any_hit is a
   constant; the two share the caller's stack. */
KDRT__W_TARGET static KDRT__FORCEINLINE void KDRT__W(kdrt__packet_walk_from)(
    const kdrt_tree *tree, kdrt__packet *p, kdrt__v t0, kdrt__v t1, int any_hit,
    KDRT__W(kdrt__packet_todo) *stack, kdrt_traversal_stats *stats)
{
    const kdrt__v zero = kdrt__v_zero();
    const kdrt__v below_slack = kdrt__v_set1(1.0f - KDRT__T_SLACK);
    const kdrt__v above_slack = kdrt__v_set1(1.0f + KDRT__T_SLACK);
    uint32_t sp = 0, node = 0;
    unsigned lanes = p->lanes;
    for (;;) {
        const kdrt__node *n = &tree->nodes[node];
        if (!kdrt__node_is_leaf(n)) {
            const uint32_t axis = kdrt__node_axis(n);
            const int negative = (int)((p->negative >> axis) & 1u);
            const kdrt__v split = kdrt__v_set1(n->u.split), o = kdrt__v_load(p->org[axis]);
            const kdrt__v t_split = kdrt__v_mul(kdrt__v_sub(split, o), kdrt__v_load(p->inv_dir[axis]));
            const kdrt__v lo = kdrt__v_mul(t_split, below_slack);
            const kdrt__v hi = kdrt__v_mul(t_split, above_slack);
            const kdrt__vm near_first = negative ? kdrt__v_cmp(o, split, _CMP_GT_OQ)
                                                 : kdrt__v_cmp(o, split, _CMP_LT_OQ);
            const kdrt__vm on_plane = kdrt__m_and(kdrt__v_cmp(t_split, zero, _CMP_EQ_OQ),
                                                  kdrt__v_cmp(t0, zero, _CMP_LE_OQ));
            const kdrt__vm near_only = kdrt__m_andnot(
                on_plane, kdrt__m_or(kdrt__v_cmp(t_split, zero, _CMP_LE_OQ), kdrt__v_cmp(lo, t1, _CMP_GT_OQ)));
            const kdrt__vm far_only = kdrt__m_andnot(kdrt__m_or(on_plane, near_only),
                                                     kdrt__v_cmp(hi, t0, _CMP_LT_OQ));
            const kdrt__vm one_side = kdrt__m_or(near_only, far_only);
            /* near only and near first, or far only and far first: the first child alone */
            const unsigned first_only = kdrt__m_bits(kdrt__m_and(one_side, kdrt__m_xor(near_first, far_only)));
            const unsigned one = kdrt__m_bits(one_side);
            const unsigned retire = lanes & kdrt__m_bits(kdrt__m_and(on_plane, near_first));
            const unsigned live = lanes & ~retire;
            const unsigned first = live & (~one | first_only), second = live & (~one | ~first_only);
            const uint32_t below = node + 1, above = kdrt__node_above(n);
            KDRT__COUNT(stats, packet_steps, 1);
            KDRT__COUNT(stats, packet_step_lanes, (uint64_t)kdrt__bit_count(lanes));
            if (retire) p->alone |= retire, p->lanes &= ~retire;
            if (first && second) {
                /* both, from the plane on (the origin on the plane: over the whole range) */
                const kdrt__vm both = kdrt__m_andnot(kdrt__m_or(one_side, on_plane), kdrt__m_all());
                KDRT_ASSERT(sp < KDRT_MAX_DEPTH);
                kdrt__v_store(stack[sp].t0, kdrt__v_blend(t0, lo, both)), kdrt__v_store(stack[sp].t1, t1);
                stack[sp].node = negative ? below : above, stack[sp].lanes = second, ++sp;
                t1 = kdrt__v_blend(kdrt__v_blend(t1, hi, both), zero, on_plane);
                node = negative ? above : below, lanes = first;
                continue;
            }
            if (first) {
                node = negative ? above : below, lanes = first;
                continue;
            }
            if (second) {
                node = negative ? below : above, lanes = second;
                continue;
            }
        } else {
            unsigned lane, cells;
            KDRT__COUNT(stats, packet_leaves, 1);
            if (p->sheared) {
                const unsigned found = KDRT__W(kdrt__packet_leaf)(tree, n, p, lanes, any_hit, stats);
                p->found |= found, p->lanes &= ~found, lanes &= ~found;
            } else {
                for (cells = lanes; cells; cells &= cells - 1u) {
                    lane = kdrt__ctz(cells);
                    if (kdrt__test_leaf_apart(tree, n, &p->s[lane], p->best[lane], any_hit, stats)) {
                        p->found |= 1u << lane, p->lanes &= ~(1u << lane);
                        continue;
                    }
                    p->bound[lane] = p->best[lane]->t;
                }
            }
            if (!any_hit) /* the lanes whose best hit so far may lie here */
                for (cells = lanes & kdrt__m_bits(kdrt__v_cmp(kdrt__v_load(p->bound), t1, _CMP_LE_OQ));
                     cells; cells &= cells - 1u)
                    p->hit_cell[kdrt__ctz(cells)] = node;
        }
        /* Next node, with the lanes still walking that start it no later than their best hit. */
        for (;;) {
            if (sp == 0) return;
            --sp;
            lanes = stack[sp].lanes & p->lanes &
                    ~kdrt__m_bits(kdrt__v_cmp(kdrt__v_load(stack[sp].t0), kdrt__v_load(p->bound), _CMP_GT_OQ));
            if (lanes) break;
        }
        node = stack[sp].node, t0 = kdrt__v_load(stack[sp].t0), t1 = kdrt__v_load(stack[sp].t1);
    }
}

KDRT__W_TARGET static void KDRT__W(kdrt__packet_walk)(const kdrt_tree *tree, kdrt__packet *p,
                                                      const float *t0, const float *t1,
                                                      int any_hit, kdrt_traversal_stats *stats)
{
    KDRT__W(kdrt__packet_todo) stack[KDRT_MAX_DEPTH];
    KDRT__COUNT(stats, packets, 1);
    KDRT__COUNT(stats, packet_lanes, (uint64_t)kdrt__bit_count(p->lanes));
    if (any_hit) KDRT__W(kdrt__packet_walk_from)(tree, p, kdrt__v_load(t0), kdrt__v_load(t1), 1, stack, stats);
    else KDRT__W(kdrt__packet_walk_from)(tree, p, kdrt__v_load(t0), kdrt__v_load(t1), 0, stack, stats);
}

/* kdrt__setup_ray and kdrt__clip_to_box for W rays at once, with their operations, so with their
   results, for the lanes that can walk as a packet: finite, no zero component, a range that
   meets the tree's box, and for the nearest hit no start cell. Of those, the lanes that share
   the first one's direction signs and largest axis are returned, set up in p (s, org, inv_dir,
   shear, bound, kx, ky, kz, negative, lo, hi, point) and t0, t1; the others are set up ray by
   ray. */
KDRT__W_TARGET static unsigned KDRT__W(kdrt__packet_setup)(const kdrt_tree *tree,
                                                           const kdrt_ray *rays, kdrt__packet *p,
                                                           float *t0, float *t1, int any_hit)
{
    const float *base = (const float *)(const void *)rays;
    const kdrt__v zero = kdrt__v_zero(), one = kdrt__v_set1(1.0f);
    kdrt__v o[3], d[3], inv[3], abs_d[3], tmin, tmax, enter, exit, x[5];
    kdrt__vm ok = kdrt__m_all(), kz1, kz2;
    float dirs[3][KDRT__PACKET_WIDTH], tmins[KDRT__PACKET_WIDTH];
    unsigned lanes, negative[3], first, left;
    int a;
    for (a = 0; a < 3; ++a) {
        o[a] = kdrt__v_gather(base + a, kdrt__vi_ray_index());
        d[a] = kdrt__v_gather(base + 4 + a, kdrt__vi_ray_index());
        inv[a] = kdrt__v_div(one, d[a]);
        abs_d[a] = kdrt__v_abs(d[a]);
        /* finite origin and direction, no zero component, a finite inverse */
        ok = kdrt__m_and(ok, kdrt__v_cmp(kdrt__v_sub(o[a], o[a]), zero, _CMP_EQ_OQ));
        ok = kdrt__m_and(ok, kdrt__v_cmp(kdrt__v_sub(d[a], d[a]), zero, _CMP_EQ_OQ));
        ok = kdrt__m_and(ok, kdrt__v_cmp(kdrt__v_sub(inv[a], inv[a]), zero, _CMP_EQ_OQ));
        ok = kdrt__m_and(ok, kdrt__v_cmp(d[a], zero, _CMP_NEQ_OQ));
        negative[a] = kdrt__m_bits(kdrt__v_cmp(d[a], zero, _CMP_LT_OQ));
    }
    tmin = kdrt__v_gather(base + 3, kdrt__vi_ray_index());
    tmax = kdrt__v_gather(base + 7, kdrt__vi_ray_index());
    ok = kdrt__m_and(ok, kdrt__v_cmp(tmin, tmin, _CMP_ORD_Q)); /* a NaN tmin: no hit */
    tmin = kdrt__v_blend(zero, tmin, kdrt__v_cmp(tmin, zero, _CMP_GT_OQ)); /* -0 and below give +0 */
    ok = kdrt__m_and(ok, kdrt__v_cmp(tmin, tmax, _CMP_LE_OQ));
    if (!any_hit) /* a start cell: the ray takes its rope walk */
        ok = kdrt__m_and(ok, kdrt__m_gather_zero(base + 8, kdrt__vi_ray_index()));
    enter = tmin, exit = tmax;
    for (a = 0; a < 3; ++a) {
        const kdrt__v ta = kdrt__v_mul(kdrt__v_sub(kdrt__v_set1(tree->bounds.min[a]), o[a]), inv[a]);
        const kdrt__v tb = kdrt__v_mul(kdrt__v_sub(kdrt__v_set1(tree->bounds.max[a]), o[a]), inv[a]);
        const kdrt__vm a_first = kdrt__v_cmp(ta, tb, _CMP_LT_OQ);
        const kdrt__v tnear = kdrt__v_mul(kdrt__v_blend(tb, ta, a_first), kdrt__v_set1(1.0f - KDRT__T_SLACK));
        const kdrt__v tfar = kdrt__v_mul(kdrt__v_blend(ta, tb, a_first), kdrt__v_set1(1.0f + KDRT__T_SLACK));
        enter = kdrt__v_blend(enter, tnear, kdrt__v_cmp(tnear, enter, _CMP_GT_OQ));
        exit = kdrt__v_blend(exit, tfar, kdrt__v_cmp(tfar, exit, _CMP_LT_OQ));
    }
    ok = kdrt__m_and(ok, kdrt__v_cmp(enter, exit, _CMP_LE_OQ));
    lanes = kdrt__m_bits(ok);
    if (!lanes) return 0;
    /* kz, the first axis of the largest |dir| (kdrt__setup_ray's): 1 where kz1 and not kz2, 2 where kz2 */
    kz1 = kdrt__v_cmp(abs_d[1], abs_d[0], _CMP_GT_OQ);
    kz2 = kdrt__v_cmp(abs_d[2], kdrt__v_blend(abs_d[0], abs_d[1], kz1), _CMP_GT_OQ);
    first = kdrt__ctz(lanes);
    {
        const unsigned m1 = kdrt__m_bits(kz1), m2 = kdrt__m_bits(kz2);
        lanes &= kdrt__same_bit(negative[0], first) & kdrt__same_bit(negative[1], first) &
                 kdrt__same_bit(negative[2], first) & kdrt__same_bit(m1, first) &
                 kdrt__same_bit(m2, first);
        p->kz = (m2 >> first) & 1u ? 2 : (m1 >> first) & 1u ? 1 : 0;
    }
    p->negative = ((negative[0] >> first) & 1u) | ((negative[1] >> first) & 1u) << 1 |
                  ((negative[2] >> first) & 1u) << 2;
    p->kx = (p->kz + 1) % 3, p->ky = (p->kx + 1) % 3;
    if ((p->negative >> p->kz) & 1u) { const int k = p->kx; p->kx = p->ky, p->ky = k; }
    kdrt__v_store(t0, enter), kdrt__v_store(t1, exit);
    kdrt__v_store(p->bound, tmax);
    for (a = 0; a < 3; ++a) {
        kdrt__v_store(p->org[a], o[a]), kdrt__v_store(p->inv_dir[a], inv[a]);
        kdrt__v_store(dirs[a], d[a]);
    }
    x[0] = o[p->kx], x[1] = o[p->ky], x[2] = o[p->kz];
    x[3] = kdrt__v_div(d[p->kx], d[p->kz]), x[4] = kdrt__v_div(d[p->ky], d[p->kz]);
    kdrt__v_store(p->shear[0], x[3]), kdrt__v_store(p->shear[1], x[4]);
    kdrt__v_store(p->shear[2], kdrt__v_div(one, d[p->kz]));
    kdrt__v_store(tmins, tmin);
    for (a = 0; a < 5; ++a) /* the bounds over the packet's lanes of their origins and shears */
        kdrt__v_range(x[a], lanes, &p->lo[a], &p->hi[a]);
    p->point = p->lo[0] == p->hi[0] && p->lo[1] == p->hi[1] && p->lo[2] == p->hi[2];
    for (left = lanes; left; left &= left - 1u) {
        const unsigned lane = kdrt__ctz(left);
        kdrt__ray_setup *s = &p->s[lane];
        for (a = 0; a < 3; ++a)
            s->org[a] = p->org[a][lane], s->dir[a] = dirs[a][lane], s->inv_dir[a] = p->inv_dir[a][lane];
        s->tmin = tmins[lane], s->tmax = p->bound[lane];
        s->list = NULL, s->rules = NULL;
        s->kx = p->kx, s->ky = p->ky, s->kz = p->kz;
        s->shear_x = p->shear[0][lane], s->shear_y = p->shear[1][lane], s->shear_z = p->shear[2][lane];
    }
    return lanes;
}

/* kdrt__batch with this kernel: W rays at a time, as a packet where they can be one. */
KDRT__W_TARGET static uint32_t KDRT__W(kdrt__batch)(const kdrt_tree *tree, const kdrt_ray *rays,
                                                    uint32_t count, kdrt_hit *hits,
                                                    uint8_t *occluded, int any_hit,
                                                    kdrt_traversal_stats *stats)
{
    const uint32_t width = KDRT__PACKET_WIDTH;
    kdrt__packet p;
    kdrt_hit scratch[KDRT__PACKET_WIDTH]; /* any_hit: the walk's hits, unused after */
    kdrt_ray last[KDRT__PACKET_WIDTH];    /* the last rays, when fewer than W, and copies of the last */
    uint32_t i, found = 0, skip = 0, failures = 0;
    for (i = 0; i < count; i += width) {
        const uint32_t n = count - i < width ? count - i : width;
        const kdrt_ray *group = rays + i;
        float t0[KDRT__PACKET_WIDTH], t1[KDRT__PACKET_WIDTH];
        unsigned lane, left, walked, alone;
        if (failures && !skip && n >= KDRT__PACKET_MIN_LANES && 2u * kdrt__same_signs(group, n) < n)
            skip = kdrt__failed_packet(&failures) + 1u; /* this group too */
        if (skip || n < KDRT__PACKET_MIN_LANES) {
            /* Incoherent rays: after packets that did not form, the next groups go straight
               to the single-ray walk, a group more each time (up to 64), before trying again.
               So do groups too small for a packet (a batch of one ray: its single call), and
               after a failure, groups whose directions mostly differ in their signs, found
               without vector code (kdrt__same_signs). */
            if (skip) --skip;
            found += any_hit ? kdrt__batch_alone(tree, rays + i, n, NULL, occluded + i, stats)
                             : kdrt__batch_alone(tree, rays + i, n, hits + i, NULL, stats);
            continue;
        }
        if (n < width) {
            for (lane = 0; lane < width; ++lane) last[lane] = rays[i + (lane < n ? lane : n - 1u)];
            group = last;
        }
        p.lanes = KDRT__W(kdrt__packet_setup)(tree, group, &p, t0, t1, any_hit) & ((1u << n) - 1u);
        /* The other rays' setup is SSE code: run with AVX's upper halves dirty, each of its
           instructions waits on them (GCC inserts no vzeroupper before these calls). */
        _mm256_zeroupper();
        p.alone = p.found = 0;
        p.sheared = tree->watertight;
        alone = 0;
        for (lane = 0; lane < n; ++lane) {
            kdrt_hit *best = any_hit ? &scratch[lane] : &hits[i + lane];
            p.best[lane] = best;
            kdrt__miss(best);
            if (!((p.lanes >> lane) & 1u)) {
                /* not in the packet: set up alone, a miss or a ray of its own */
                kdrt__ray_setup *s = &p.s[lane];
                if (!kdrt__setup_ray(&group[lane], s) ||
                    !kdrt__clip_to_box(&tree->bounds, s, &t0[lane], &t1[lane]))
                    continue;
                alone |= 1u << lane;
            }
            best->t = p.s[lane].tmax;
            p.hit_cell[lane] = 0;
        }
        if (!kdrt__packet_together(tree, &p)) alone |= p.lanes, p.lanes = 0;
        walked = p.lanes;
        if (walked) failures = 0;
        else skip = kdrt__failed_packet(&failures);
        if (walked) KDRT__W(kdrt__packet_walk)(tree, &p, t0, t1, any_hit, stats);
        walked &= ~p.alone;
        for (left = p.alone; left; left &= left - 1u) { /* handed back during the walk: anew */
            const unsigned l = kdrt__ctz(left);
            kdrt__miss(p.best[l]);
            p.best[l]->t = p.s[l].tmax;
        }
        alone |= p.alone;
        for (lane = 0; lane < n; ++lane) {
            const unsigned bit = 1u << lane;
            int hit;
            if (alone & bit)
                hit = kdrt__walk_alone(tree, group[lane].cell, &p.s[lane], t0[lane], t1[lane],
                                       p.best[lane], any_hit, stats);
            else if (any_hit) hit = (p.found & bit) != 0;
            else {
                hit = p.best[lane]->triangle != KDRT_INVALID_ID;
                if (hit && (walked & bit)) p.best[lane]->cell = p.hit_cell[lane];
            }
            if (any_hit) occluded[i + lane] = (uint8_t)hit;
            found += (uint32_t)hit;
        }
    }
    return found;
}
#endif /* KDRT__PACKET_PARTS & 2 */

#undef KDRT__W
#undef KDRT__W_TARGET
#undef KDRT__NEAREST
#undef kdrt__v
#undef kdrt__vm
#undef kdrt__vd
#undef kdrt__vdm
#undef kdrt__v_set1
#undef kdrt__v_zero
#undef kdrt__v_load
#undef kdrt__v_store
#undef kdrt__v_add
#undef kdrt__v_sub
#undef kdrt__v_mul
#undef kdrt__v_div
#undef kdrt__v_abs
#undef kdrt__v_cmp
#undef kdrt__v_blend
#undef kdrt__v_gather
#undef kdrt__v_range
#undef kdrt__m_gather_zero
#undef kdrt__m_and
#undef kdrt__m_or
#undef kdrt__m_xor
#undef kdrt__m_andnot
#undef kdrt__m_all
#undef kdrt__m_none
#undef kdrt__m_bits
#undef kdrt__vd_zero
#undef kdrt__vd_set1
#undef kdrt__vd_add
#undef kdrt__vd_sub
#undef kdrt__vd_mul
#undef kdrt__vd_div
#undef kdrt__vd_cmp
#undef kdrt__md_and
#undef kdrt__md_or
#undef kdrt__md_andnot
#undef kdrt__md_bits
#undef kdrt__vd_widen
#undef kdrt__vd_half
#undef kdrt__vd_store_ps
#undef kdrt__vi_ray_index
#endif /* KDRT__PACKET_WIDTH */

/*
   MIT No Attribution

   Copyright 2026 the kdrt authors

   Permission is hereby granted, free of charge, to any person obtaining a copy of this software
   and associated documentation files (the "Software"), to deal in the Software without
   restriction, including without limitation the rights to use, copy, modify, merge, publish,
   distribute, sublicense, and/or sell copies of the Software, and to permit persons to whom the
   Software is furnished to do so.

   THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND, EXPRESS OR IMPLIED, INCLUDING
   BUT NOT LIMITED TO THE WARRANTIES OF MERCHANTABILITY, FITNESS FOR A PARTICULAR PURPOSE AND
   NONINFRINGEMENT. IN NO EVENT SHALL THE AUTHORS OR COPYRIGHT HOLDERS BE LIABLE FOR ANY CLAIM,
   DAMAGES OR OTHER LIABILITY, WHETHER IN AN ACTION OF CONTRACT, TORT OR OTHERWISE, ARISING FROM,
   OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE USE OR OTHER DEALINGS IN THE SOFTWARE.
*/
