#include "server/net/wire_convert.hpp"

#include <google/protobuf/reflection.h>

namespace vox::net {
namespace {

world::Vec3 from_wire(const wire::Vec3& v) { return {v.x(), v.y(), v.z()}; }

// Wire materials are uint32; the world's are 0..255.
bool material_fits(uint32_t m) { return m <= 255; }

}  // namespace

wire::ChunkCoord to_wire(world::ChunkCoord c) {
  wire::ChunkCoord w;
  w.set_x(c.x);
  w.set_y(c.y);
  w.set_z(c.z);
  return w;
}

world::ChunkCoord from_wire(const wire::ChunkCoord& c) { return {c.x(), c.y(), c.z()}; }

WireEdit edit_from_wire(const wire::Edit& e) {
  WireEdit out;
  auto refuse = [&out](wire::EditResult::Status s, std::string why) {
    out.status = s;
    out.reason = std::move(why);
    return out;
  };
  switch (e.kind_case()) {
    case wire::Edit::kBrush: {
      const auto& b = e.brush();
      if (!material_fits(b.material()))
        return refuse(wire::EditResult::BAD_MATERIAL, "material must be 0..255");
      world::Brush brush{from_wire(b.center()), b.radius(), b.strength(), b.remove(), std::nullopt};
      if (b.material() != 0) brush.material = static_cast<world::Material>(b.material());
      out.edit = brush;
      break;
    }
    case wire::Edit::kExplosion:
      out.edit = world::Explosion{from_wire(e.explosion().center()), e.explosion().radius(),
                                  e.explosion().power()};
      break;
    case wire::Edit::kSmooth:
      out.edit =
          world::Smooth{from_wire(e.smooth().center()), e.smooth().radius(), e.smooth().strength()};
      break;
    case wire::Edit::kPaint: {
      const auto& p = e.paint();
      if (!material_fits(p.material()))
        return refuse(wire::EditResult::BAD_MATERIAL, "material must be 1..255");
      out.edit = world::Paint{from_wire(p.center()), p.radius(),
                              static_cast<world::Material>(p.material())};
      break;
    }
    case wire::Edit::kStamp: {
      const auto& s = e.stamp();
      if (!wire::Stamp::Shape_IsValid(s.shape())) {
        out.unknown_enum = true;
        return refuse(wire::EditResult::BAD_VALUE,
                      "unknown stamp shape " + std::to_string(s.shape()));
      }
      if (!material_fits(s.material()))
        return refuse(wire::EditResult::BAD_MATERIAL, "material must be 1..255");
      world::Stamp stamp;
      stamp.shape = s.shape() == wire::Stamp::SPHERE ? world::Stamp::Shape::kSphere
                                                     : world::Stamp::Shape::kBox;
      stamp.min = from_wire(s.min());
      stamp.max = from_wire(s.max());
      stamp.center = from_wire(s.center());
      stamp.radius = s.radius();
      stamp.solid = s.solid();
      stamp.material = static_cast<world::Material>(s.material());
      out.edit = stamp;
      break;
    }
    case wire::Edit::KIND_NOT_SET:
      return refuse(wire::EditResult::MISSING_EDIT, "the Edit carries no edit");
  }
  return out;
}

wire::EditResult::Status status_of(world::RefusalReason r) {
  switch (r) {
    case world::RefusalReason::kNone:
      return wire::EditResult::ACCEPTED;
    case world::RefusalReason::kNotFinite:
      return wire::EditResult::NOT_FINITE;
    case world::RefusalReason::kOutOfBounds:
      return wire::EditResult::OUT_OF_BOUNDS;
    case world::RefusalReason::kBadRadius:
      return wire::EditResult::BAD_RADIUS;
    case world::RefusalReason::kBadStrength:
      return wire::EditResult::BAD_STRENGTH;
    case world::RefusalReason::kBadMaterial:
      return wire::EditResult::BAD_MATERIAL;
    case world::RefusalReason::kShuttingDown:
      return wire::EditResult::SHUTTING_DOWN;
    case world::RefusalReason::kServerBusy:
      return wire::EditResult::SERVER_BUSY;
    case world::RefusalReason::kOverBudget:
      return wire::EditResult::RATE_LIMITED;
    case world::RefusalReason::kStorageUnavailable:
      return wire::EditResult::STORAGE_UNAVAILABLE;
    case world::RefusalReason::kForbidden:
      return wire::EditResult::FORBIDDEN;
  }
  return wire::EditResult::ACCEPTED;
}

wire::Envelope edit_result_message(uint64_t request, const pipeline::EditResult& r) {
  // SERVER_BUSY: memory frees as eviction runs (several times a second under pressure).
  constexpr uint32_t kBusyRetryMs = 1000;
  wire::Envelope result;
  auto* w = result.mutable_edit_result();
  w->set_request_id(request);
  w->set_status(r.accepted ? wire::EditResult::ACCEPTED : status_of(r.reason));
  w->set_reason(r.message);
  if (r.reason == world::RefusalReason::kServerBusy ||
      r.reason == world::RefusalReason::kStorageUnavailable)
    w->set_retry_after_ms(kBusyRetryMs);
  for (const world::ChunkCoord& c : r.changed_chunks) *w->add_changed_chunks() = to_wire(c);
  for (const uint64_t region : r.clipped_by) w->add_clipped_by(region);
  if (r.already_applied) w->set_already_applied(true);
  if (r.accepted)
    for (const world::MaterialVolume& v : r.volumes) {
      auto* out = w->add_volumes();
      out->set_material(v.material);
      out->set_removed(v.removed);
      out->set_added(v.added);
    }
  return result;
}

bool has_unknown_fields(const google::protobuf::Message& m) {
  const google::protobuf::Reflection* r = m.GetReflection();
  if (!r->GetUnknownFields(m).empty()) return true;
  std::vector<const google::protobuf::FieldDescriptor*> fields;
  r->ListFields(m, &fields);
  for (const auto* f : fields) {
    if (f->cpp_type() != google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE) continue;
    if (f->is_repeated()) {
      for (int i = 0; i < r->FieldSize(m, f); ++i) {
        if (has_unknown_fields(r->GetRepeatedMessage(m, f, i))) return true;
      }
    } else if (has_unknown_fields(r->GetMessage(m, f))) {
      return true;
    }
  }
  return false;
}

wire::Region to_wire(const world::Region& r) {
  wire::Region w;
  w.set_id(r.id);
  w.set_name(r.name);
  auto* b = w.mutable_box();
  b->set_min_x(r.box.lo[0]), b->set_min_y(r.box.lo[1]), b->set_min_z(r.box.lo[2]);
  b->set_max_x(r.box.hi[0]), b->set_max_y(r.box.hi[1]), b->set_max_z(r.box.hi[2]);
  w.set_protect_build((r.flags & world::kProtectBuild) != 0);
  w.set_protect_explode((r.flags & world::kProtectExplode) != 0);
  for (const std::string& o : r.owners) w.add_owners(o);
  w.set_created_by(r.created_by);
  w.set_created_unix_ms(r.created_unix_ms);
  return w;
}

world::Region region_from_wire(const wire::Region& w) {
  world::Region r;
  r.name = w.name();
  const auto& b = w.box();
  r.box = {{b.min_x(), b.min_y(), b.min_z()}, {b.max_x(), b.max_y(), b.max_z()}};
  r.flags = static_cast<uint8_t>((w.protect_build() ? world::kProtectBuild : 0) |
                                 (w.protect_explode() ? world::kProtectExplode : 0));
  r.owners.assign(w.owners().begin(), w.owners().end());
  return r;
}

wire::RegionResult::Status status_of(pipeline::RegionOutcome::Status s) {
  using S = pipeline::RegionOutcome::Status;
  switch (s) {
    case S::kOk:
      return wire::RegionResult::OK;
    case S::kBadValue:
      return wire::RegionResult::BAD_VALUE;
    case S::kNotFound:
      return wire::RegionResult::NOT_FOUND;
    case S::kTooMany:
      return wire::RegionResult::TOO_MANY;
    case S::kStorageUnavailable:
      return wire::RegionResult::STORAGE_UNAVAILABLE;
    case S::kShuttingDown:
      return wire::RegionResult::SHUTTING_DOWN;
  }
  return wire::RegionResult::BAD_VALUE;
}

}  // namespace vox::net
