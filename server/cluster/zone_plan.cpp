#include "server/cluster/zone_plan.hpp"

#include <algorithm>

namespace vox::cluster {

ZonePlan plan_zones(const std::set<world::ZoneId>& held, const std::set<world::ZoneId>& interest,
                    std::vector<std::string> live, const std::string& self) {
  if (std::find(live.begin(), live.end(), self) == live.end()) live.push_back(self);
  const auto first_is_self = [&](world::ZoneId z) {
    return live[*world::first_ranked(z, live)] == self;
  };
  ZonePlan plan;
  for (const world::ZoneId z : held) (first_is_self(z) ? plan.renew : plan.hand_off).push_back(z);
  for (const world::ZoneId z : interest) {
    if (!held.contains(z) && first_is_self(z)) plan.take.push_back(z);
  }
  return plan;
}

}  // namespace vox::cluster
