// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78, initial value and final xor
// 0xFFFFFFFF), as in iSCSI, ext4 and most languages' standard libraries.
#pragma once

#include <cstddef>
#include <cstdint>

namespace vox::proto {

uint32_t crc32c(const uint8_t* data, size_t size);

}  // namespace vox::proto
