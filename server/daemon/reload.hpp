// What a SIGHUP changes while voxeld runs (the README, "Reloading the configuration"): the
// command line and --config file are read again; the log level, the token key (a new key
// for an old one: an open server stays open), the edit budgets and the connection caps
// take their new values; any other flag whose value changed keeps its old one and is
// named as needing a restart. Pure; any thread.
#pragma once

#include <set>
#include <string>
#include <vector>

#include "server/daemon/voxeld_flags.hpp"

namespace vox::daemon {

// The flags a reload applies.
const std::set<std::string>& reloadable_flags();

struct ReloadPlan {
  std::vector<std::string> changed;  // "edit-budget: 300000 -> 1000", to apply
  std::vector<std::string> kept;     // "port: 7777 -> 7778 needs a restart (still 7777)"
  // `now` with the reloadable flags of `next`: what runs once applied.
  VoxeldConfig after;
};
ReloadPlan plan_reload(const VoxeldConfig& now, const VoxeldConfig& next);

}  // namespace vox::daemon
