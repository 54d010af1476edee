// What a node does with its zones in one ownership round (docs/CLUSTER.md): pure
// bookkeeping, no I/O; ZoneKeeper runs it every lease / 3 with what the database says.
//
// - A zone this node holds and still ranks first for among the live nodes: renew.
// - One it holds but another live node now ranks first for (that node joined): hand off
//   (stop taking its edits, let pending appends land, release), so that node takes it.
// - One it is interested in (asked to take, or its own players edit there), does not hold,
//   and ranks first for: try to take it (it is taken only if free; a live lease of another
//   node makes the attempt fail, and the next round tries again).
// - This node always counts as live (its own heartbeat may lag a round behind).
#pragma once

#include <set>
#include <string>
#include <vector>

#include "server/world/zone.hpp"

namespace vox::cluster {

struct ZonePlan {
  std::vector<world::ZoneId> renew, hand_off, take;
};

// `held`: the zones this node holds; `interest`: zones it should own if it ranks first
// (held ones need not be repeated); `live`: the live nodes' ids (this node's included
// or not: it is always counted).
ZonePlan plan_zones(const std::set<world::ZoneId>& held, const std::set<world::ZoneId>& interest,
                    std::vector<std::string> live, const std::string& self);

}  // namespace vox::cluster
