// Stream framing: each message is a 4-byte little-endian length followed by that many
// bytes (a serialized Envelope). The decoder is incremental and never trusts a length:
// anything over the limit is an error before any allocation.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace google::protobuf {
class MessageLite;
}

namespace vox::proto {

inline constexpr size_t kFrameHeaderBytes = 4;

void append_frame(std::span<const uint8_t> body, std::vector<uint8_t>& out);
// The message framed, appended to `out` (serialized in place, no temporary).
void append_framed(const google::protobuf::MessageLite& message, std::vector<uint8_t>& out);
uint32_t read_frame_length(const uint8_t* header);

// Feed bytes as they arrive; pop complete frames.
class FrameDecoder {
 public:
  explicit FrameDecoder(size_t max_frame_bytes) : max_(max_frame_bytes) {}
  void feed(std::span<const uint8_t> bytes);
  // A complete frame's body, nullopt when more bytes are needed. After an error (a
  // length over the limit) it returns nullopt forever and error() says why.
  std::optional<std::vector<uint8_t>> next();
  const std::string& error() const { return error_; }
  size_t buffered() const { return buffer_.size() - start_; }

 private:
  size_t max_;
  std::vector<uint8_t> buffer_;
  size_t start_ = 0;
  std::string error_;
};

}  // namespace vox::proto
