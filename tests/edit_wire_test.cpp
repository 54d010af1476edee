// Edits forwarded between cluster nodes and their answers (server/cluster/edit_wire.hpp):
// there and back, and any damaged, cut or lengthened message refused with a reason.
#include "server/cluster/edit_wire.hpp"

#include <gtest/gtest.h>

#include "server/store/edit_codec.hpp"

namespace vox::cluster {
namespace {

EditRequest a_request() {
  EditRequest r;
  r.id = 77;
  r.bypass_regions = true;
  r.author = "player-9";
  r.edit = world::Brush{{10.5f, -3.0f, 7.25f}, 4.0f, 0.5f, false, 3};
  return r;
}

EditReply a_reply() {
  EditReply r;
  r.id = 77;
  r.reason = world::RefusalReason::kNone;
  r.message = "";
  r.zones = {{{-1, 2}, 40}, {{0, 2}, 9}};
  r.changed_chunks = {{-1, 0, 5}, {2147483647, -2147483647 - 1, 0}};
  r.clipped_by = {3, 4};
  return r;
}

TEST(EditWire, ARequestAndAReplyGoThereAndBack) {
  const auto req = decode_edit_request(encode_edit_request(a_request()));
  ASSERT_TRUE(req);
  EXPECT_EQ(req->id, 77u);
  EXPECT_TRUE(req->bypass_regions);
  EXPECT_EQ(req->author, "player-9");
  EXPECT_EQ(store::encode_edit(req->edit), store::encode_edit(a_request().edit));
  EXPECT_EQ(req->edit_id, 0u);
  EXPECT_FALSE(req->part);
  // One zone's part of an edit across zones: its edit id and zone come along.
  EditRequest part = a_request();
  part.edit_id = 0xfedcba9876543210ULL;
  part.part = world::ZoneId{-3, 2147483647};
  const auto back_part = decode_edit_request(encode_edit_request(part));
  ASSERT_TRUE(back_part);
  EXPECT_EQ(back_part->edit_id, part.edit_id);
  ASSERT_TRUE(back_part->part);
  EXPECT_EQ(*back_part->part, *part.part);
  EXPECT_TRUE(back_part->bypass_regions);
  EXPECT_EQ(back_part->author, "player-9");
  const auto rep = decode_edit_reply(encode_edit_reply(a_reply()));
  ASSERT_TRUE(rep);
  EXPECT_EQ(rep->id, 77u);
  EXPECT_EQ(rep->reason, world::RefusalReason::kNone);
  ASSERT_EQ(rep->zones.size(), 2u);
  EXPECT_EQ(rep->zones[0].first, (world::ZoneId{-1, 2}));
  EXPECT_EQ(rep->zones[0].second, 40u);
  EXPECT_EQ(rep->changed_chunks, a_reply().changed_chunks);
  EXPECT_EQ(rep->clipped_by, a_reply().clipped_by);
  EditReply refused = a_reply();
  refused.reason = world::RefusalReason::kStorageUnavailable;
  refused.message = "zone (1, 2) is being loaded on this node; retry shortly";
  const auto back = decode_edit_reply(encode_edit_reply(refused));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->reason, world::RefusalReason::kStorageUnavailable);
  EXPECT_EQ(back->message, refused.message);
  EXPECT_FALSE(back->zone_moving || back->already_applied);
  refused.zone_moving = true;
  EditReply resent = a_reply();
  resent.already_applied = true;
  EXPECT_TRUE(decode_edit_reply(encode_edit_reply(refused))->zone_moving);
  EXPECT_TRUE(decode_edit_reply(encode_edit_reply(resent))->already_applied);
}

TEST(EditWire, CutLengthenedOrDamagedMessagesAreRefusedWithAReason) {
  const std::vector<uint8_t> request = encode_edit_request(a_request());
  const std::vector<uint8_t> reply = encode_edit_reply(a_reply());
  std::string why;
  for (size_t cut = 0; cut < reply.size(); ++cut) {
    EXPECT_FALSE(decode_edit_reply(std::span(reply).first(cut), &why)) << cut;
    EXPECT_FALSE(why.empty());
  }
  for (size_t cut = 0; cut < request.size(); ++cut)
    EXPECT_FALSE(decode_edit_request(std::span(request).first(cut), &why)) << cut;
  std::vector<uint8_t> longer = reply;
  longer.push_back(0);
  EXPECT_FALSE(decode_edit_reply(longer, &why));
  std::vector<uint8_t> bad = reply;
  bad[10] = 200;  // a reason no build defines
  EXPECT_FALSE(decode_edit_reply(bad, &why));
  bad = request;
  bad[10] = 2;  // flags this version does not define
  EXPECT_FALSE(decode_edit_request(bad, &why));
  EXPECT_FALSE(decode_edit_request(reply, &why));  // a reply is no request
  EXPECT_FALSE(decode_edit_reply(request, &why));
  // Every byte flipped in turn: refused or decoded, never a crash (ASan/UBSan watch).
  for (size_t i = 0; i < reply.size(); ++i) {
    std::vector<uint8_t> flipped = reply;
    flipped[i] ^= 0xff;
    (void)decode_edit_reply(flipped, &why);
  }
  for (size_t i = 0; i < request.size(); ++i) {
    std::vector<uint8_t> flipped = request;
    flipped[i] ^= 0xff;
    (void)decode_edit_request(flipped, &why);
  }
}

}  // namespace
}  // namespace vox::cluster
