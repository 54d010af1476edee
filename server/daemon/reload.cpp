#include "server/daemon/reload.hpp"

namespace vox::daemon {

namespace {

std::string joined(const std::vector<std::string>& values) {
  if (values.empty()) return "(none)";
  std::string s;
  for (const std::string& v : values) s += (s.empty() ? "" : ", ") + v;
  return s;
}

}  // namespace

const std::set<std::string>& reloadable_flags() {
  static const std::set<std::string> flags = {"log-level",         "auth-public-key",
                                              "edit-budget",       "edit-burst",
                                              "admin-edit-budget", "admin-edit-burst",
                                              "max-clients",       "max-handshaking",
                                              "max-per-address",   "max-handshaking-per-address"};
  return flags;
}

ReloadPlan plan_reload(const VoxeldConfig& now, const VoxeldConfig& next) {
  ReloadPlan plan{{}, {}, now};
  const auto value = [](const VoxeldConfig& c, const std::string& key) {
    const auto it = c.effective.find(key);
    return it == c.effective.end() ? std::vector<std::string>{} : it->second;
  };
  std::set<std::string> keys;
  for (const auto& [key, v] : now.effective) keys.insert(key);
  for (const auto& [key, v] : next.effective) keys.insert(key);
  for (const std::string& key : keys) {
    const std::vector<std::string> was = value(now, key), is = value(next, key);
    const bool key_file = key == "auth-public-key";
    // The key file may hold a new key under the same name.
    const bool differs = was != is || (key_file && now.net.auth_key != next.net.auth_key);
    if (!differs) continue;
    std::string line = key + ": " + joined(was) + " -> " + joined(is);
    if (key_file && now.net.auth_key && next.net.auth_key && was == is) line += " (a new key)";
    const bool open_switch =
        key_file && (now.net.auth_key.has_value() != next.net.auth_key.has_value());
    if (reloadable_flags().count(key) == 0 || open_switch) {
      plan.kept.push_back(line + (open_switch ? " needs a restart (between an open server and "
                                                "player tokens; still " +
                                                    joined(was) + ")"
                                              : " needs a restart (still " + joined(was) + ")"));
      continue;
    }
    plan.changed.push_back(line);
    plan.after.effective[key] = is;
  }
  // The reloadable values themselves (those unchanged are the same anyway).
  plan.after.log_level = next.log_level;
  if (now.net.auth_key.has_value() == next.net.auth_key.has_value())
    plan.after.net.auth_key = next.net.auth_key;
  plan.after.net.edit_budget_rate = next.net.edit_budget_rate;
  plan.after.net.edit_budget_burst = next.net.edit_budget_burst;
  plan.after.net.admin_edit_budget_rate = next.net.admin_edit_budget_rate;
  plan.after.net.admin_edit_budget_burst = next.net.admin_edit_budget_burst;
  plan.after.net.max_clients = next.net.max_clients;
  plan.after.net.max_handshaking = next.net.max_handshaking;
  plan.after.net.max_per_address = next.net.max_per_address;
  plan.after.net.max_handshaking_per_address = next.net.max_handshaking_per_address;
  return plan;
}

}  // namespace vox::daemon
