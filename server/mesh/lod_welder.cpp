#include "server/mesh/lod_welder.hpp"

#include <algorithm>
#include <bit>
#include <tuple>
#include <unordered_map>

namespace vox::mesh {
namespace {

struct PositionHash {
  size_t operator()(const std::array<uint32_t, 3>& p) const {
    return (uint64_t{p[0]} * 0x9E3779B97F4A7C15ull) ^ (uint64_t{p[1]} * 0xC2B2AE3D27D4EB4Full) ^
           (uint64_t{p[2]} * 0x165667B19E3779F9ull);
  }
};

}  // namespace

ChunkMesh weld_lod_parts(std::vector<LodPart> parts) {
  std::sort(parts.begin(), parts.end(), [](const LodPart& a, const LodPart& b) {
    return std::tie(a.level, a.chunk) < std::tie(b.level, b.chunk);
  });
  std::unordered_map<std::array<uint32_t, 3>, uint32_t, PositionHash> index;
  ChunkMesh out;
  std::vector<uint32_t> remap;
  for (const LodPart& part : parts) {
    const ChunkMesh& m = *part.mesh;
    const float scale = static_cast<float>(1u << part.level), side = 32.0f * scale;
    const float o[3] = {static_cast<float>(part.chunk[0]) * side,
                        static_cast<float>(part.chunk[1]) * side,
                        static_cast<float>(part.chunk[2]) * side};
    remap.assign(m.positions.size(), UINT32_MAX);
    for (const uint32_t i : m.indices) {
      if (remap[i] == UINT32_MAX) {
        const Vec3f p{o[0] + m.positions[i].x * scale, o[1] + m.positions[i].y * scale,
                      o[2] + m.positions[i].z * scale};
        const std::array<uint32_t, 3> bits{std::bit_cast<uint32_t>(p.x),
                                           std::bit_cast<uint32_t>(p.y),
                                           std::bit_cast<uint32_t>(p.z)};
        const auto [it, added] =
            index.try_emplace(bits, static_cast<uint32_t>(out.positions.size()));
        if (added) {
          out.positions.push_back(p);
          out.normals.push_back(m.normals[i]);
          out.materials.push_back(m.materials[i]);
        }
        remap[i] = it->second;
      }
      out.indices.push_back(remap[i]);
    }
  }
  return out;
}

}  // namespace vox::mesh
