#pragma once
// `bisturi demo`: builds DLFL solids (the seed's figures and a large torus) and reports their
// statistics. The main job until the session runtime exists.

#include <cstddef>

namespace bisturi::cli {

struct MeshDemoOptions {
  std::size_t torus_segments =
      256;  ///< the large torus has segments x segments/2 quads x 2 triangles
  bool json = false;
  bool quiet = false;
};

/// Returns the process exit code (0: every solid validated and has the expected topology).
int run_mesh_demo(const MeshDemoOptions& options);

}  // namespace bisturi::cli
