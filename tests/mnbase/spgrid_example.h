// The seed's GPU SPGrid (section 0.9.8) and its documented byte layout, shared by the host and GPU tests.
#pragma once

#include <cstddef>

#include "MnBase/Memory/structural_instance.h"

namespace fbar::test {

/// SoA, no padding: the layout Claymore uses for its grid.
using spgrid_decorator =
    decorator<structural_allocation_policy::full_allocation, structural_padding_policy::compact, attrib_layout::soa>;
/// One 4x4x4 grid block of 4 f32 channels (mass, momentum x, y, z).
using grid_block_ = structural<structural_type::dense, domain<char, 4, 4, 4>, spgrid_decorator, f32_, f32_, f32_, f32_>;
/// The grid buffer: a run-time number of blocks.
using grid_buffer_ = structural<structural_type::dynamic, dynamic_domain<int>, spgrid_decorator, grid_block_>;

inline constexpr std::size_t spgrid_channels = 4;
inline constexpr std::size_t spgrid_nodes_per_block = 64;
inline constexpr std::size_t spgrid_block_bytes = spgrid_channels * spgrid_nodes_per_block * sizeof(float);  // 1024

/// Documented layout (Library/MnBase/Memory/README.md): block b starts at b * 1024; inside it channel c
/// is one array of 64 floats (c * 64 * 4); node (x, y, z) is its row-major index x*16 + y*4 + z.
constexpr std::size_t spgrid_byte_offset(std::size_t b, std::size_t c, std::size_t x, std::size_t y, std::size_t z) {
  return b * spgrid_block_bytes + c * spgrid_nodes_per_block * sizeof(float) + (x * 16 + y * 4 + z) * sizeof(float);
}

}  // namespace fbar::test
