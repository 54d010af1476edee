// The 256-case marching-cubes tables in the classic layout of P. Bourke, "Polygonising a
// scalar field" (1994), tables by C. Bloyd: edgeTable[case] is a 12-bit mask of the cut
// edges, triTable[case] lists up to 5 triangles as edge numbers, -1 terminated.
//
// Cube numbering (Bourke): corners 0 (0,0,0) 1 (1,0,0) 2 (1,1,0) 3 (0,1,0)
// 4 (0,0,1) 5 (1,0,1) 6 (1,1,1) 7 (0,1,1); edges 0:0-1 1:1-2 2:2-3 3:3-0 4:4-5 5:5-6
// 6:6-7 7:7-4 8:0-4 9:1-5 10:2-6 11:3-7. Bit i of a case is set when corner i is solid.
//
// The triangle table is derived at compile time from the cube's faces (see the .cpp), so
// its ambiguous faces follow one stated rule and its triangles wind counter-clockwise seen
// from the air side.
#pragma once

#include <array>
#include <cstdint>

namespace vox::mesh {

// The revision of the published table (docs/marching_cubes_tables.txt, Welcome): 2 since
// no fan puts a triangle flat in a cube face (8 cases changed).
inline constexpr uint32_t kMeshTableRevision = 2;

extern const std::array<uint16_t, 256> edgeTable;
extern const std::array<std::array<int8_t, 16>, 256> triTable;

inline constexpr std::array<std::array<int8_t, 3>, 8> kCubeCorner = {{
    {0, 0, 0},
    {1, 0, 0},
    {1, 1, 0},
    {0, 1, 0},
    {0, 0, 1},
    {1, 0, 1},
    {1, 1, 1},
    {0, 1, 1},
}};
inline constexpr std::array<std::array<int8_t, 2>, 12> kEdgeCorners = {{
    {0, 1},
    {1, 2},
    {2, 3},
    {3, 0},
    {4, 5},
    {5, 6},
    {6, 7},
    {7, 4},
    {0, 4},
    {1, 5},
    {2, 6},
    {3, 7},
}};
// The 6 faces, corners counter-clockwise as seen from outside the cube.
inline constexpr std::array<std::array<int8_t, 4>, 6> kCubeFaces = {{
    {0, 3, 2, 1},  // z = 0
    {4, 5, 6, 7},  // z = 1
    {0, 1, 5, 4},  // y = 0
    {3, 7, 6, 2},  // y = 1
    {0, 4, 7, 3},  // x = 0
    {1, 2, 6, 5},  // x = 1
}};

}  // namespace vox::mesh
