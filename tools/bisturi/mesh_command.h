#pragma once
// `bisturi mesh info FILE` and `bisturi mesh convert IN OUT`: read any supported mesh file,
// build its DLFL (procedures 3-6) and report its topology, or write it in another format.

#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct MeshOptions {
  std::string input;
  std::string output;
  bool json = false;
  bool weld = false;
  double weld_tolerance = 0.0;
  std::string ply_encoding = "binary";
};

/// Adds the `mesh` command with its `info` and `convert` sub-commands; `run` is set to the
/// action the parsed command line asks for.
void add_mesh_command(CLI::App& app, MeshOptions& options, int (*&run)(const MeshOptions&));

int run_mesh_info(const MeshOptions& options);
int run_mesh_convert(const MeshOptions& options);

}  // namespace bisturi::cli
