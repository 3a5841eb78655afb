// hfsmc: action and service servers scripted by an `hfsmc test` scenario, answered by the
// `ros2` playback fake (hfsmc/ros2_servers.hpp; the twin of hfsmc_ros2_servers.py).
#include "hfsmc/ros2_servers.hpp"

#include <algorithm>
#include <exception>

namespace hfsmc {
namespace ros2 {
namespace rpc {

namespace {

Decoded message(const json::Value* v, const Decode& decode, const std::string& n, const std::string& type,
                const std::function<void(const std::string&)>& bad) {
  if (v == nullptr || v->kind == json::Value::NUL) return Decoded{};
  Bytes bytes;
  if (v->kind != json::Value::STRING || !unbase64(v->text, bytes))
    bad("`servers." + n + "`: no " + type + ": not base64 text");
  try {
    return decode(bytes.data(), bytes.size());
  } catch (const std::exception& e) {
    bad("`servers." + n + "`: no " + type + ": " + e.what());
  }
  return Decoded{};
}

}  // namespace

Holding Scripted::convert(const json::Value& servers, const std::vector<Decl>& decls,
                          const std::function<void(const std::string&)>& bad) {
  Holding out;
  if (servers.kind != json::Value::OBJECT) bad("`servers` must be a mapping");
  for (const auto& m : servers.members) {
    const std::string& n = m.first;
    const json::Value& p = m.second;
    std::size_t k = decls.size();
    std::string listed;
    for (std::size_t i = 0; i < decls.size(); ++i) {
      if (decls[i].key == n) k = i;
      listed += (listed.empty() ? "" : ", ") + decls[i].key;
    }
    if (k == decls.size())
      bad("no action or service `" + n + "` (" + (listed.empty() ? "none" : listed) + ")");
    if (p.kind == json::Value::NUL) {
      out.emplace_back(k, nullptr);
      continue;
    }
    if (p.kind != json::Value::OBJECT) bad("`servers." + n + "` must be a mapping or null");
    const Decl& d = decls[k];
    auto s = std::make_shared<Server>();
    const json::Value* after = p.get("after_us");
    if (after != nullptr && after->kind != json::Value::NUL) {
      if (after->kind != json::Value::NUMBER || !after->integer || after->as_int < 0)
        bad("`servers." + n + ".after_us` must be a whole number >= 0 or null");
      s->after_us = after->as_int;
    }
    if (!d.action) {
      s->after_us = std::max(s->after_us, 0LL);
      s->message = message(p.get("response"), d.response, n, d.type + " response", bad);
      out.emplace_back(k, std::move(s));
      continue;
    }
    const json::Value* accept = p.get("accept");
    const json::Value* end = p.get("end");
    if ((accept != nullptr && accept->kind != json::Value::BOOL) ||
        (end != nullptr && (end->kind != json::Value::STRING || (end->text != "succeeded" && end->text != "aborted"))))
      bad("`servers." + n + "`: `accept` true or false, `end` one of succeeded, aborted");
    s->accept = accept == nullptr || accept->b;
    if (end != nullptr) s->end = end->text;
    if (const json::Value* fb = p.get("feedback"); fb != nullptr && fb->kind != json::Value::NUL) {
      if (fb->kind != json::Value::ARRAY) bad("`servers." + n + ".feedback`: a list of [after_us, CDR]");
      for (const json::Value& item : fb->items) {
        if (item.kind != json::Value::ARRAY || item.items.size() != 2 || item.items[0].kind != json::Value::NUMBER ||
            !item.items[0].integer)
          bad("`servers." + n + ".feedback`: a list of [after_us, CDR]");
        s->feedback.emplace_back(item.items[0].as_int,
                                 message(&item.items[1], d.feedback, n, d.type + " feedback", bad));
      }
      std::stable_sort(s->feedback.begin(), s->feedback.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
    }
    s->message = message(p.get("result"), d.result, n, d.type + " result", bad);
    out.emplace_back(k, std::move(s));
  }
  return out;
}

void Scripted::start(const std::vector<Decl>& decls, bool every) {
  every_ = every;
  named_.assign(decls.size(), false);
  held_.assign(decls.size(), nullptr);
  sent_.assign(decls.size(), Sent{});
  blank_.clear();
  for (const Decl& d : decls) blank_.push_back(d.blank ? d.blank() : Decoded{});
}

void Scripted::hold(const Holding& given) {
  for (const auto& g : given) {
    named_[g.first] = true;
    held_[g.first] = g.second;
  }
}

void Scripted::send(std::size_t k, long long t_us) {
  const Held& server = held_[k];
  sent_[k] = Sent{true, t_us, server != nullptr ? t_us : -1, server, -1};
}

void Scripted::cancel(std::size_t k, long long t_us) {
  if (sent_[k].any) sent_[k].cancelled = t_us;
}

bool Scripted::answer(std::size_t k, const Decl& d, long long now, State& out) {
  Sent& s = sent_[k];
  if (!s.any) return false;
  if (s.at < 0 && held_[k] != nullptr) {  // delivered to the server that holds now
    s.at = now;
    s.server = held_[k];
  }
  out = State{};
  if (now <= s.t0) {
    out.status = "pending";
    return true;
  }
  const bool late = d.timeout >= 0 && static_cast<double>(now - s.t0) >= d.timeout * 1e6;
  if (!d.action) {
    if (s.at >= 0 && now > s.at && now - s.at >= s.server->after_us) {
      out.status = "done";
      out.a = s.server->message.msg ? s.server->message : blank_[k];
    } else {
      out.status = late ? "timeout" : s.at >= 0 ? "pending" : "no_server";
    }
    return true;
  }
  if (s.at < 0 || now <= s.at) {
    out.status = late ? "timeout" : s.at < 0 ? "no_server" : "pending";
    return true;
  }
  const Server& server = *s.server;
  if (!server.accept) {
    out.status = "rejected";
    return true;
  }
  if (s.cancelled >= 0 && now > s.cancelled) {
    out.status = "canceled";
    out.b = blank_[k];
    return true;
  }
  for (const auto& f : server.feedback)
    if (f.first <= now - s.at) out.a = f.second;
  if (server.after_us >= 0 && now - s.at >= server.after_us) {
    out.status = server.end;
    out.b = server.message.msg ? server.message : blank_[k];
  } else {
    out.status = late ? "timeout" : "executing";
  }
  return true;
}

}  // namespace rpc
}  // namespace ros2
}  // namespace hfsmc
