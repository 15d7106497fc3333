#include "mesh_demo.h"

#include <unistd.h>
#include <chrono>
#include <cstdio>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"

namespace bisturi::cli {

namespace {

struct Expected {
  std::size_t parts;
  std::int64_t chi_each;    // Euler characteristic of every part
  std::size_t rings_total;  // labelled faces
  std::size_t non_manifold_vertices;
  std::size_t non_manifold_edges;
};

struct DemoSolid {
  std::string name;
  std::function<Dlfl(const BuildOptions&)> build;
  Expected expected;
};

PolygonMesh without_last_face(PolygonMesh m) {
  m.offsets.pop_back();
  m.indices.resize(m.offsets.back());
  return m;
}

Dlfl two_tetrahedra_sharing_a_vertex(const BuildOptions& options) {
  Dlfl dlfl;
  const auto first = append_oriented_manifold(dlfl, tetrahedron_mesh(), options);
  PolygonMesh second = tetrahedron_mesh();
  for (auto& p : second.positions)
    p = -p;  // mirrored through the shared vertex at the origin
  BuildOptions join = options;
  join.join_vertices.assign(4, VertexId{});
  join.join_vertices[0] = first[0];
  append_oriented_manifold(dlfl, second, join);
  return dlfl;
}

Dlfl two_cubes_sharing_an_edge(const BuildOptions& options) {
  Dlfl dlfl;
  const auto a = append_oriented_manifold(dlfl, cube_mesh({0, 0, 0}, 1.0), options);
  BuildOptions join = options;
  join.join_vertices.assign(8, VertexId{});
  join.join_vertices[0] = a[3];  // (1, 1, 0)
  join.join_vertices[4] = a[7];  // (1, 1, 1)
  append_oriented_manifold(dlfl, cube_mesh({1, 1, 0}, 1.0), join);
  return dlfl;
}

nlohmann::json statistics_json(const MeshStatistics& s) {
  nlohmann::json parts = nlohmann::json::array();
  for (const auto& p : s.parts) {
    parts.push_back({{"vertices", p.vertices},
                     {"edges", p.edges},
                     {"faces", p.faces},
                     {"rings", p.rings},
                     {"euler_characteristic", p.euler_characteristic},
                     {"genus", p.genus}});
  }
  return {{"vertices", s.vertices},
          {"corners", s.corners},
          {"faces", s.faces},
          {"edges", s.edges},
          {"rotations", s.rotations},
          {"bounding_faces", s.bounding_faces},
          {"non_manifold_vertices", s.non_manifold_vertices},
          {"non_manifold_edges", s.non_manifold_edges},
          {"parts", parts}};
}

std::string check_expected(const MeshStatistics& s, const Expected& e) {
  if (s.parts.size() != e.parts) return "expected " + std::to_string(e.parts) + " parts";
  for (const auto& p : s.parts) {
    if (p.euler_characteristic != e.chi_each) {
      return "expected every part to have chi = " + std::to_string(e.chi_each);
    }
  }
  if (s.bounding_faces != e.rings_total)
    return "expected " + std::to_string(e.rings_total) + " rings";
  if (s.non_manifold_vertices != e.non_manifold_vertices) return "unexpected non-manifold vertices";
  if (s.non_manifold_edges != e.non_manifold_edges) return "unexpected non-manifold edges";
  return {};
}

}  // namespace

int run_mesh_demo(const MeshDemoOptions& options) {
  const std::size_t n = options.torus_segments;
  std::vector<DemoSolid> solids = {
      {"closed tetrahedron",
       [](const BuildOptions& o) { return build_oriented_manifold(tetrahedron_mesh(), o); },
       {1, 2, 0, 0, 0}},
      {"open chalice (tetrahedron without its top)",
       [](const BuildOptions& o) {
         return build_oriented_manifold(without_last_face(tetrahedron_mesh()), o);
       },
       {1, 1, 1, 0, 0}},
      {"two tetrahedra sharing a vertex", two_tetrahedra_sharing_a_vertex, {2, 2, 0, 1, 0}},
      {"two cubes sharing an edge", two_cubes_sharing_an_edge, {2, 2, 0, 2, 1}},
      {"open vessel segment (tube)",
       [](const BuildOptions& o) {
         return build_oriented_manifold(tube_mesh(12.5, 40.0, 48, 32), o);
       },
       {1, 0, 2, 0, 0}},
      {"torus, " + std::to_string(n * n) + " triangles",
       [n](const BuildOptions& o) {
         return build_oriented_manifold(torus_mesh(40.0, 12.0, n, n / 2, true), o);
       },
       {1, 0, 0, 0, 0}},
  };

  nlohmann::json report = {{"solids", nlohmann::json::array()}};
  int exit_code = 0;
  for (const DemoSolid& solid : solids) {
    BuildOptions build_options;
    const bool show_progress = !options.quiet && isatty(STDERR_FILENO) != 0;
    if (show_progress) {
      build_options.progress = [&solid](std::size_t done, std::size_t total) {
        std::fprintf(stderr, "\rbuilding %s: %3zu%%", solid.name.c_str(), done * 100 / total);
        std::fflush(stderr);
      };
    }
    const auto start = std::chrono::steady_clock::now();
    const Dlfl dlfl = solid.build(build_options);
    const double build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (show_progress) std::fprintf(stderr, "\r\033[K");
    const ValidationReport validation = validate(dlfl);
    const MeshStatistics stats = mesh_statistics(dlfl);
    const std::string mismatch = check_expected(stats, solid.expected);
    const bool ok = validation.ok() && mismatch.empty();
    if (!ok) exit_code = 1;

    nlohmann::json entry = statistics_json(stats);
    entry["name"] = solid.name;
    entry["valid"] = validation.ok();
    entry["expected_topology"] = mismatch.empty();
    entry["build_ms"] = build_ms;
    entry["bytes_per_face"] =
        double(dlfl.memory_bytes()) / double(stats.faces - stats.bounding_faces);
    if (!validation.ok()) entry["problems"] = validation.problems;
    if (!mismatch.empty()) entry["mismatch"] = mismatch;
    report["solids"].push_back(entry);

    if (!options.json) {
      std::cout << solid.name << "\n"
                << "  V " << stats.vertices << "  E " << stats.edges << "  F " << stats.faces
                << " (" << stats.bounding_faces << " labelled)  rotations " << stats.rotations
                << "  corners " << stats.corners << "\n"
                << "  non-manifold: " << stats.non_manifold_vertices << " vertices, "
                << stats.non_manifold_edges << " edges\n";
      for (std::size_t i = 0; i < stats.parts.size(); ++i) {
        const auto& p = stats.parts[i];
        std::cout << "  part " << i << ": V " << p.vertices << " E " << p.edges << " F " << p.faces
                  << " rings " << p.rings << "  chi " << p.euler_characteristic << "  genus "
                  << p.genus << "\n";
      }
      std::cout << "  built in " << build_ms << " ms, " << entry["bytes_per_face"].get<double>()
                << " bytes/face, validate: " << (validation.ok() ? "ok" : "FAILED") << "\n";
      if (!validation.ok()) std::cout << validation.summary();
      if (!mismatch.empty()) std::cout << "  unexpected topology: " << mismatch << "\n";
    }
  }
  report["ok"] = exit_code == 0;
  if (options.json) std::cout << report.dump(2) << "\n";
  return exit_code;
}

}  // namespace bisturi::cli
