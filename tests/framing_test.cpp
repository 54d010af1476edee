#include "proto/framing.hpp"

#include <gtest/gtest.h>

namespace vox::proto {
namespace {

TEST(FrameDecoder, ReassemblesFramesSplitAnywhere) {
  std::vector<uint8_t> stream;
  const std::vector<uint8_t> a = {1, 2, 3}, b = {}, c(1000, 7);
  append_frame(a, stream);
  append_frame(b, stream);
  append_frame(c, stream);
  for (size_t step = 1; step <= stream.size(); step = step * 2 + 1) {
    FrameDecoder d(4096);
    std::vector<std::vector<uint8_t>> got;
    for (size_t i = 0; i < stream.size(); i += step) {
      d.feed(std::span(stream).subspan(i, std::min(step, stream.size() - i)));
      while (auto f = d.next()) got.push_back(*f);
    }
    ASSERT_EQ(got.size(), 3u) << "step " << step;
    EXPECT_EQ(got[0], a);
    EXPECT_EQ(got[1], b);
    EXPECT_EQ(got[2], c);
  }
}

TEST(FrameDecoder, RejectsEveryTruncationAsIncomplete) {
  std::vector<uint8_t> frame;
  append_frame(std::vector<uint8_t>(50, 9), frame);
  for (size_t n = 0; n < frame.size(); ++n) {
    FrameDecoder d(4096);
    d.feed(std::span(frame).first(n));
    EXPECT_FALSE(d.next()) << "length " << n;
    EXPECT_TRUE(d.error().empty());
  }
}

TEST(FrameDecoder, RefusesALengthOverTheLimitBeforeAllocating) {
  FrameDecoder d(100);
  const uint8_t header[4] = {0xFF, 0xFF, 0xFF, 0xFF};
  d.feed(header);
  EXPECT_FALSE(d.next());
  EXPECT_NE(d.error().find("over the limit"), std::string::npos);
  d.feed(header);  // stays failed
  EXPECT_FALSE(d.next());
}

}  // namespace
}  // namespace vox::proto
