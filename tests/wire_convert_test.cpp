// server/net/wire_convert: wire messages into world edits, with the checks that belong to
// the wire (materials over 255, unknown enum values, unknown fields, a missing edit).
#include "server/net/wire_convert.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "client/voxel_client.hpp"
#include "server/world/edit.hpp"

namespace vox::net {
namespace {

// An Edit as the server parses it from the wire.
wire::Edit parsed(const std::string& bytes) {
  wire::Edit e;
  EXPECT_TRUE(e.ParseFromString(bytes));
  return e;
}

// The status the server answers an Edit with before queueing it: the wire's refusal, else
// the world's validation.
wire::EditResult::Status status_for(const wire::Edit& e) {
  const WireEdit w = edit_from_wire(e);
  if (!w.edit) return w.status;
  const auto refusal = world::validate(*w.edit, world::EditLimits{});
  return refusal ? status_of(refusal->reason) : wire::EditResult::ACCEPTED;
}

wire::Edit brush_with_material(uint32_t material) {
  wire::Edit e = client::make_brush(1, 0, 10, 0, 3, 1, false).edit();
  e.mutable_brush()->set_material(material);
  return e;
}

TEST(WireConvert, ChunkCoordsRoundTripAtTheInt32Extremes) {
  constexpr int32_t lo = std::numeric_limits<int32_t>::min(),
                    hi = std::numeric_limits<int32_t>::max();
  for (const world::ChunkCoord c : {world::ChunkCoord{0, 0, 0}, world::ChunkCoord{-1, 2, -3},
                                    world::ChunkCoord{lo, hi, lo}, world::ChunkCoord{hi, lo, hi}}) {
    wire::ChunkCoord w;
    ASSERT_TRUE(w.ParseFromString(to_wire(c).SerializeAsString()));
    const world::ChunkCoord back = from_wire(w);
    EXPECT_EQ(back, c) << c.x << "," << c.y << "," << c.z;
  }
}

TEST(WireConvert, BrushMaterialZeroKeepsTheExistingOneAndOver255IsRefused) {
  const WireEdit keep = edit_from_wire(brush_with_material(0));
  ASSERT_TRUE(keep.edit);
  EXPECT_FALSE(std::get<world::Brush>(*keep.edit).material) << "0: keep the existing material";
  const WireEdit top = edit_from_wire(brush_with_material(255));
  ASSERT_TRUE(top.edit);
  EXPECT_EQ(std::get<world::Brush>(*top.edit).material, world::Material{255});
  for (const uint32_t m : {256u, 257u, 65536u + 3, std::numeric_limits<uint32_t>::max()}) {
    const WireEdit over = edit_from_wire(brush_with_material(m));
    EXPECT_FALSE(over.edit) << m << " must not wrap to " << (m & 0xFF);
    EXPECT_EQ(over.status, wire::EditResult::BAD_MATERIAL) << m;
    EXPECT_FALSE(over.unknown_enum);
  }
}

TEST(WireConvert, PaintAndSolidStampMaterialsOutside1To255AreRefusedBadMaterial) {
  for (const uint32_t m : {0u, 256u, std::numeric_limits<uint32_t>::max()}) {
    wire::Edit paint;
    paint.mutable_paint()->set_radius(2);
    paint.mutable_paint()->set_material(m);
    EXPECT_EQ(status_for(paint), wire::EditResult::BAD_MATERIAL) << "paint " << m;
    wire::Edit stamp;
    auto* s = stamp.mutable_stamp();
    s->set_shape(wire::Stamp::SPHERE);
    s->set_radius(2);
    s->set_solid(true);
    s->set_material(m);
    EXPECT_EQ(status_for(stamp), wire::EditResult::BAD_MATERIAL) << "stamp " << m;
  }
  wire::Edit carve;  // carving to air needs no material
  carve.mutable_stamp()->set_shape(wire::Stamp::SPHERE);
  carve.mutable_stamp()->set_radius(2);
  EXPECT_EQ(status_for(carve), wire::EditResult::ACCEPTED);
}

// Proto3 keeps an enum value it does not know in the field: the converter must refuse it,
// not read it as a box.
TEST(WireConvert, UnknownStampShapeIsRefusedAsAnUnknownEnum) {
  // Edit { request_id: 1, stamp { shape: 7 } } and the same with shape -1 (ten-byte varint).
  const std::string shape_7("\x08\x01\x32\x02\x08\x07", 6);
  const std::string shape_minus_1 =
      std::string("\x08\x01\x32\x0B\x08", 5) + std::string(9, '\xFF') + std::string("\x01", 1);
  for (const auto& bytes : {shape_7, shape_minus_1}) {
    const wire::Edit e = parsed(bytes);
    ASSERT_TRUE(e.has_stamp());
    EXPECT_FALSE(wire::Stamp::Shape_IsValid(e.stamp().shape()));
    const WireEdit w = edit_from_wire(e);
    EXPECT_FALSE(w.edit) << "shape " << e.stamp().shape();
    EXPECT_EQ(w.status, wire::EditResult::BAD_VALUE);
    EXPECT_TRUE(w.unknown_enum);
    EXPECT_NE(w.reason.find(std::to_string(e.stamp().shape())), std::string::npos) << w.reason;
  }
}

TEST(WireConvert, StampShapesAndFieldsReachTheWorldEdit) {
  wire::Edit e;
  auto* s = e.mutable_stamp();
  s->set_shape(wire::Stamp::BOX);
  s->mutable_min()->set_x(-4);
  s->mutable_max()->set_z(9);
  s->set_solid(true);
  s->set_material(200);
  WireEdit w = edit_from_wire(e);
  ASSERT_TRUE(w.edit);
  auto box = std::get<world::Stamp>(*w.edit);
  EXPECT_EQ(box.shape, world::Stamp::Shape::kBox);
  EXPECT_EQ(box.min.x, -4);
  EXPECT_EQ(box.max.z, 9);
  EXPECT_TRUE(box.solid);
  EXPECT_EQ(box.material, 200);
  s->set_shape(wire::Stamp::SPHERE);
  s->mutable_center()->set_y(5);
  s->set_radius(3);
  w = edit_from_wire(e);
  ASSERT_TRUE(w.edit);
  const auto sphere = std::get<world::Stamp>(*w.edit);
  EXPECT_EQ(sphere.shape, world::Stamp::Shape::kSphere);
  EXPECT_EQ(sphere.center.y, 5);
  EXPECT_EQ(sphere.radius, 3);
}

TEST(WireConvert, AnEditWithoutAKindIsRefusedMissingEdit) {
  wire::Edit e;
  e.set_request_id(5);
  const WireEdit w = edit_from_wire(e);
  EXPECT_FALSE(w.edit);
  EXPECT_EQ(w.status, wire::EditResult::MISSING_EDIT);
  EXPECT_FALSE(w.unknown_enum);
}

// Floats pass the wire as they are; the world's validation refuses what is not finite or
// out of range, and status_of names it.
TEST(WireConvert, NonFiniteAndOutOfRangeValuesAreRefusedWithTheirOwnStatus) {
  const float nan = std::numeric_limits<float>::quiet_NaN(),
              inf = std::numeric_limits<float>::infinity();
  wire::Edit e = brush_with_material(0);
  e.mutable_brush()->mutable_center()->set_x(nan);
  EXPECT_EQ(status_for(e), wire::EditResult::NOT_FINITE);
  e = brush_with_material(0);
  e.mutable_brush()->set_radius(inf);
  EXPECT_EQ(status_for(e), wire::EditResult::NOT_FINITE);
  e = brush_with_material(0);
  e.mutable_brush()->set_radius(-1);
  EXPECT_EQ(status_for(e), wire::EditResult::BAD_RADIUS);
  e = brush_with_material(0);
  e.mutable_brush()->set_strength(0);
  EXPECT_EQ(status_for(e), wire::EditResult::BAD_STRENGTH);
  e = brush_with_material(0);
  e.mutable_brush()->mutable_center()->set_x(3e9f);
  EXPECT_EQ(status_for(e), wire::EditResult::OUT_OF_BOUNDS);
  wire::Edit x;
  x.mutable_explosion()->set_radius(2);
  x.mutable_explosion()->set_power(-inf);
  EXPECT_EQ(status_for(x), wire::EditResult::NOT_FINITE);
}

TEST(WireConvert, StatusOfGivesEveryRefusalReasonItsOwnStatus) {
  using R = world::RefusalReason;
  using S = wire::EditResult;
  const std::pair<R, S::Status> expected[] = {{R::kNone, S::ACCEPTED},
                                              {R::kNotFinite, S::NOT_FINITE},
                                              {R::kOutOfBounds, S::OUT_OF_BOUNDS},
                                              {R::kBadRadius, S::BAD_RADIUS},
                                              {R::kBadStrength, S::BAD_STRENGTH},
                                              {R::kBadMaterial, S::BAD_MATERIAL},
                                              {R::kShuttingDown, S::SHUTTING_DOWN},
                                              {R::kServerBusy, S::SERVER_BUSY},
                                              {R::kOverBudget, S::RATE_LIMITED}};
  for (const auto& [reason, status] : expected)
    EXPECT_EQ(status_of(reason), status) << world::to_string(reason);
}

TEST(WireConvert, UnknownFieldsAreFoundAtAnyDepth) {
  wire::Envelope edit, resync;
  edit.mutable_edit()->mutable_brush()->mutable_center()->set_x(1);
  resync.mutable_resync()->add_coords()->set_x(1);
  resync.mutable_resync()->add_coords()->set_y(2);
  EXPECT_FALSE(has_unknown_fields(edit));
  EXPECT_FALSE(has_unknown_fields(resync));

  auto with_unknown = [](wire::Envelope m, auto&& where) {
    google::protobuf::Message& inner = where(m);
    inner.GetReflection()->MutableUnknownFields(&inner)->AddVarint(99, 1);
    // Through the wire, as the server sees it.
    wire::Envelope parsed;
    EXPECT_TRUE(parsed.ParseFromString(m.SerializeAsString()));
    return parsed;
  };
  EXPECT_TRUE(has_unknown_fields(
      with_unknown(edit, [](wire::Envelope& m) -> google::protobuf::Message& { return m; })));
  EXPECT_TRUE(has_unknown_fields(with_unknown(
      edit, [](wire::Envelope& m) -> google::protobuf::Message& { return *m.mutable_edit(); })));
  EXPECT_TRUE(
      has_unknown_fields(with_unknown(edit, [](wire::Envelope& m) -> google::protobuf::Message& {
        return *m.mutable_edit()->mutable_brush()->mutable_center();
      })));
  EXPECT_TRUE(
      has_unknown_fields(with_unknown(resync, [](wire::Envelope& m) -> google::protobuf::Message& {
        return *m.mutable_resync()->mutable_coords(1);  // the second of a repeated field
      })));
}

}  // namespace
}  // namespace vox::net
