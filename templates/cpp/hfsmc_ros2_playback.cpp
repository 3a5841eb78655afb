// hfsmc: the `ros2` interface fed from a playback (`hfsmc replay`, `hfsmc test`): no DDS.
//
// The C++ twin of templates/python/hfsmc_ros2_playback.py (schemas/recording.md,
// "Playback"). The script's snapshot entries of the interface are read and checked when the
// interface starts, each sample's CDR (base64) decoded by the generated message type, so a
// script whose bytes do not decode is refused before anything runs (one line, exit 2). At
// each instant the entries up to it are applied over what held before; in a scenario's
// script (not `recorded`) a field left out follows the samples: `count` +1 per sample, `age`
// the time since the latest sample's entry, `publishers` 1 from the first. A recorded
// script's names the model does not have are left out, and what the model has and the
// entry lacks is no evidence: a query of it is written to DIR/unanswered.jsonl. A scenario's
// `servers` (scripted action and service servers, hfsmc/ros2_servers.hpp) answer the goals
// and calls the model sends.
#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "hfsmc/base64.hpp"
#include "hfsmc/playback.hpp"
#include "hfsmc/ros2_interface.hpp"

namespace hfsmc {
namespace ros2 {

void Interface::read_script() {
  const std::vector<playback::Entry>& entries = inputs_->entries(name_);
  fed_.assign(decls_.size(), Fed{});
  fed_subscribers_.assign(decls_.size(), 0);
  // A scenario's script: no server unless it scripts one. A script that gives the goals' and
  // calls' values itself (a recording, or one written by hand) answers with those.
  bool gives = false;
  for (const playback::Entry& e : entries) {
    std::vector<std::string> missing = e.unrecorded;
    script_.push_back(convert(e, missing));
    marks_.push_back(playback::Entry{e.t, e.line, json::Value{}, std::move(missing)});
    for (const char* key : {"goals", "calls"})
      if (const json::Value* v = e.values.get(key))
        gives = gives || (v->kind == json::Value::OBJECT && !v->members.empty());
  }
  servers_.start(rpc_.decls(), !inputs_->recorded() && !gives);
}

Interface::FedEntry Interface::convert(const playback::Entry& e, std::vector<std::string>& missing) const {
  const playback::Inputs& in = *inputs_;
  const bool recorded = in.recorded();
  const std::string who = "interface `" + name_ + "`: ";
  const auto bad = [&](const std::string& what) { in.bad(e.line, who + what); };
  const auto find = [&](const std::string& key, bool publication) -> const Decl* {
    for (const Decl& d : decls_)
      if (d.key == key && d.publication == publication) return &d;
    return nullptr;
  };
  const auto listed = [&](bool publication) {
    std::string out;
    for (const Decl& d : decls_)
      if (d.publication == publication) out += (out.empty() ? "" : ", ") + d.key;
    return out.empty() ? std::string("none") : out;
  };
  const auto whole = [&](const json::Value& v, const std::string& what) -> long long {
    if (v.kind != json::Value::NUMBER || !v.integer || v.as_int < 0) bad(what + " must be a whole number >= 0");
    return v.as_int;
  };
  const auto table = [&](const json::Value* v, const char* what) -> const json::Value* {
    if (v == nullptr || v->kind == json::Value::NUL) return nullptr;
    if (v->kind != json::Value::OBJECT) bad(std::string(what) + " must be a mapping");
    return v;
  };
  FedEntry out{e.t, {}, {}, {}, {}};
  for (const auto& m : e.values.members)
    if (m.first != "subscriptions" && m.first != "subscribers" && m.first != "goals" && m.first != "calls" &&
        (recorded || m.first != "servers"))
      bad("the ros2 interface `" + name_ + "` has no snapshot field `" + m.first +
          "` (subscriptions, subscribers, goals, calls" + (recorded ? ")" : ", servers)"));
  if (const json::Value* v = e.values.get("servers"))
    out.servers = rpc::Scripted::convert(*v, rpc_.decls(), bad);
  std::vector<bool> rpc_named(rpc_.decls().size(), false);
  for (const char* key : {"goals", "calls"}) {
    if (const json::Value* v = e.values.get(key)) {
      auto given = rpc_.convert(*v, key[0] == 'g', recorded, bad, rpc_named);
      out.rpcs.insert(out.rpcs.end(), given.begin(), given.end());
    }
  }
  if (recorded)  // an action or service of the model the recorded run did not have
    for (std::size_t k = 0; k < rpc_named.size(); ++k)
      if (!rpc_named[k]) missing.push_back(rpc_.decls()[k].key);
  std::vector<bool> named(decls_.size(), false);
  if (const json::Value* subs = table(e.values.get("subscriptions"), "subscriptions")) {
    for (const auto& m : subs->members) {
      const Decl* d = find(m.first, false);
      if (d == nullptr && recorded) continue;  // a topic of the recorded model only
      if (d == nullptr)
        bad("the ros2 interface `" + name_ + "` has no subscription `" + m.first + "` (subscriptions: " +
            listed(false) + ")");
      Given g;
      g.k = index(*d);
      named[g.k] = true;
      const std::string n = "`" + d->key + "`";
      if (m.second.kind != json::Value::OBJECT) bad("subscription " + n + " must be a mapping");
      for (const auto& f : m.second.members) {
        const std::string& k = f.first;
        const json::Value& v = f.second;
        if (k == "count") {
          g.count = true;
          g.values.count = static_cast<long>(whole(v, n + "'s count"));
        } else if (k == "publishers") {
          g.publishers = true;
          g.values.publishers = static_cast<int>(std::min<long long>(whole(v, n + "'s publishers"), 1 << 30));
        } else if (k == "dropped") {
          g.dropped = true;
          g.values.dropped = static_cast<long>(whole(v, n + "'s dropped"));
        } else if (k == "age") {
          g.age = true;
          if (v.kind == json::Value::STRING && v.text == "inf") {
            g.values.age = std::numeric_limits<double>::infinity();
          } else if (v.kind == json::Value::NUMBER && v.number >= 0) {
            g.values.age = v.number;
          } else {
            bad(n + "'s age must be a number of seconds >= 0, or \"inf\"");
          }
        } else if (k == "cdr") {
          g.cdr = true;
          g.values.arrived = e.t;
          if (v.kind == json::Value::NUL) continue;
          std::vector<std::uint8_t> bytes;
          if (v.kind != json::Value::STRING) bad(n + "'s cdr must be base64 text");
          if (!unbase64(v.text, bytes)) bad(n + "'s cdr is not base64");
          try {
            g.values.msg = d->decode(bytes.data(), bytes.size());
          } catch (const std::exception& x) {
            bad(n + "'s sample is no " + d->type + ": " + x.what());
          }
          g.values.cdr = std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
        } else {
          bad("subscription " + n + " has no field `" + k + "` (count, age, publishers, dropped, cdr)");
        }
      }
      out.subs.push_back(std::move(g));
    }
  }
  if (const json::Value* pubs = table(e.values.get("subscribers"), "subscribers")) {
    for (const auto& m : pubs->members) {
      const Decl* d = find(m.first, true);
      if (d == nullptr && recorded) continue;
      if (d == nullptr)
        bad("the ros2 interface `" + name_ + "` has no publication `" + m.first + "` (publications: " +
            listed(true) + ")");
      named[index(*d)] = true;
      const long long k = whole(m.second, "`" + d->key + "`'s subscribers");
      out.subscribers.emplace_back(index(*d), static_cast<int>(std::min<long long>(k, 1 << 30)));
    }
  }
  if (recorded)  // what the model has and the recorded run did not: not evidence
    for (std::size_t k = 0; k < decls_.size(); ++k)
      if (!named[k]) missing.push_back(decls_[k].key);
  return out;
}

void Interface::fake_snapshot(long long t_us) {
  for (; next_ < script_.size() && script_[next_].t <= t_us; ++next_) {
    const FedEntry& e = script_[next_];
    for (const Given& g : e.subs) {
      Fed& f = fed_[g.k];
      if (g.cdr && !g.count) f.count += g.values.cdr != nullptr ? 1 : 0;
      if (g.count) f.count = g.values.count;
      if (g.age) f.age = g.values.age;
      if (g.publishers) f.publishers = g.values.publishers;
      if (g.dropped) f.dropped = g.values.dropped;
      if (g.cdr) {
        f.msg = g.values.msg;
        f.cdr = g.values.cdr;
        f.arrived = g.values.arrived;
      }
    }
    for (const auto& s : e.subscribers) fed_subscribers_[s.first] = s.second;
    rpc_.apply(e.rpcs);
    servers_.hold(e.servers);
  }
  rpc_.fake_snapshot();
  for (std::size_t k = 0; k < rpc_.decls().size(); ++k) {  // what the scripted servers answer
    const rpc::Decl& d = rpc_.decls()[k];
    rpc::State answered;
    if (servers_.answer(k, d, t_us, answered)) rpc_.state(d) = std::move(answered);
  }
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    Snap& s = snap_[k];
    if (decls_[k].publication) {
      s.matched = fed_subscribers_[k];
      continue;
    }
    const Fed& f = fed_[k];
    s.count = f.count;
    s.age = f.age >= 0 ? f.age
            : (f.arrived >= 0 && f.count) ? static_cast<double>(t_us - f.arrived) / 1e6
                                          : std::numeric_limits<double>::infinity();
    s.matched = f.publishers >= 0 ? f.publishers : (f.count ? 1 : 0);
    s.dropped = f.dropped;
    s.msg = f.msg.get();
    s.cdr = f.cdr;
  }
  evidence_.at(inputs_, name_, t_us, next_ > 0 ? &marks_[next_ - 1] : nullptr, -1);
}

const void* Interface::fake_message(const char* key) const {
  for (std::size_t k = 0; k < decls_.size(); ++k)
    if (!decls_[k].publication && decls_[k].key == key) return snap_[k].msg;
  return nullptr;
}

}  // namespace ros2
}  // namespace hfsmc
