// hfsmc/ros2_intro.hpp: the automaton on ROS 2 from a C++ component (SPEC 5.4, docs/ros2.md
// "The automaton on ROS 2"), the twin of hfsmc_ros2intro.py. Copied into a C++ component
// only when a `ros2` interface of its model has `introspection: true` (its yasmin_msgs types
// are generated only then); included by that interface's generated class.
//
// From the node the interface already is, it publishes
// - `/fsm_viewer`: the structure and the active states as yasmin_msgs/msg/StateMachine, the
//   message YASMIN's viewer reads;
// - `~/hfsm/status`: the monitor's snapshot (schemas/monitor.md) as JSON in a
//   std_msgs/msg/String, with `name`, for `ros2 topic echo`;
// both at 4 Hz and at the end of every instant in which a state was entered or left, and a
// last time when the component stops. The bytes are the Python component's for the same
// model and instant: the same tree (states depth first, regions as machines), the same JSON
// (json.dumps(..., ensure_ascii=False, separators=(",", ":"))).
//
// An Observer of the engine (observer.hpp): every call on the automaton's thread. Never under
// --playback (there is no node), and not when NAME.yaml turns it off.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hfsmc/json.hpp"
#include "hfsmc/observer.hpp"
#include "hfsmc/ros2.hpp"
#include "hfsmc/viewstate.hpp"
#include "std_msgs/msg/string.hpp"
#include "yasmin_msgs/msg/state_machine.hpp"

namespace hfsmc {
namespace ros2 {
namespace intro {

inline constexpr const char* kFsmViewer = "/fsm_viewer";  // YASMIN's: one for every machine
inline constexpr const char* kStatus = "~/hfsm/status";  // the node's own
// The node's keys of its two writers: not identifiers, so never a model's topic's name.
inline constexpr const char* kMachineKey = "~introspection/machine";
inline constexpr const char* kStatusKey = "~introspection/status";
inline constexpr double kEverySeconds = 0.25;  // 4 Hz: the viewer forgets a machine after 3 s

// The name the viewer shows and keys the machine by: the node's, after its namespace's
// parts joined with dots (`tb2.patrol`), as the viewer's URLs take no `/`.
inline std::string machine_name(const std::string& node, const std::string& ns) {
  std::string out;
  std::size_t k = 0;
  while (k < ns.size()) {
    const std::size_t slash = ns.find('/', k);
    const std::size_t end = slash == std::string::npos ? ns.size() : slash;
    if (end > k) out += ns.substr(k, end - k) + ".";
    k = end + 1;
  }
  return out + node;
}

// JSON as json.dumps(ensure_ascii=False) writes it, from json_string()'s ensure_ascii=True
// text: each \uXXXX of a character beyond ASCII (a surrogate pair for one beyond U+FFFF)
// becomes its UTF-8 bytes; the escapes of quotes, backslashes and control characters stay.
inline std::string unescape_non_ascii(const std::string& json) {
  const auto hex4 = [&](std::size_t at, unsigned& v) {
    if (at + 6 > json.size() || json[at] != '\\' || json[at + 1] != 'u') return false;
    v = 0;
    for (std::size_t i = at + 2; i < at + 6; ++i) {
      const char c = json[i];
      v = v * 16 + static_cast<unsigned>(c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10);
    }
    return true;
  };
  std::string out;
  out.reserve(json.size());
  for (std::size_t k = 0; k < json.size();) {
    unsigned cp = 0;
    if (json[k] != '\\') {
      out += json[k++];
      continue;
    }
    if (!hex4(k, cp) || cp < 0x80) {  // an escape kept as it is: two characters, or six
      const std::size_t n = json[k + 1] == 'u' ? 6 : 2;
      out.append(json, k, n);
      k += n;
      continue;
    }
    std::size_t used = 6;
    unsigned low = 0;
    if (cp >= 0xD800 && cp < 0xDC00 && hex4(k + 6, low) && low >= 0xDC00 && low < 0xE000) {
      cp = 0x10000 + ((cp - 0xD800) << 10) + (low - 0xDC00);
      used = 12;
    } else if (cp >= 0xD800 && cp < 0xE000) {  // a lone surrogate: no UTF-8 for it
      out.append(json, k, 6);
      k += 6;
      continue;
    }
    if (cp < 0x800) {
      out += static_cast<char>(0xC0 | (cp >> 6));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xE0 | (cp >> 12));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (cp >> 18));
      out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    }
    out += static_cast<char>(0x80 | (cp & 0x3F));
    k += used;
  }
  return out;
}

// The YASMIN view of the structure, computed once at start: the component first, then every
// state and region depth first in model order. A state with a sub-automaton (its own or a
// used file's) is a machine; a state with regions is a machine whose states are its regions.
class Tree {
 public:
  void build(const ViewState& view, const std::string& root_name, const Structure& s) {
    root_name_ = root_name;
    paths_.assign(1, "");
    visit(view, "");
    for (std::size_t i = 0; i < paths_.size(); ++i) ids_[paths_[i]] = static_cast<int>(i);
    std::vector<const Structure::Transition*> trs;
    for (const auto& tr : s.transitions) trs.push_back(&tr);
    std::stable_sort(trs.begin(), trs.end(), [](const auto* a, const auto* b) {
      return a->from != b->from ? a->from < b->from : a->index < b->index;
    });
    for (const auto* tr : trs) {
      const std::string label = tr->name.empty() ? "t" + std::to_string(tr->index) : tr->name;
      outgoing_[tr->from].emplace_back(label, tr->to.substr(tr->to.rfind('/') + 1));
    }
  }

  // The StateMachine of the view's active states now.
  yasmin_msgs::msg::StateMachine message(const ViewState& view) const {
    yasmin_msgs::msg::StateMachine m;
    for (std::size_t i = 0; i < paths_.size(); ++i) {
      const std::string& p = paths_[i];
      const std::vector<std::string>& kids = view.children.at(p);
      yasmin_msgs::msg::State st;
      st.id = static_cast<std::int32_t>(i);
      st.parent = p.empty() ? -1 : ids_.at(p.substr(0, p.rfind('/') == std::string::npos ? 0 : p.rfind('/')));
      st.name = p.empty() ? root_name_ : p.substr(p.rfind('/') + 1);
      auto out = outgoing_.find(p);
      if (out != outgoing_.end()) {
        for (const auto& [outcome, target] : out->second) {
          yasmin_msgs::msg::Transition t;
          t.outcome = outcome;
          t.state = target;
          st.transitions.push_back(t);
          st.outcomes.push_back(outcome);
        }
      }
      st.is_fsm = !kids.empty();
      st.current_state = kids.empty() ? -1 : current(view, p, kids);
      m.states.push_back(std::move(st));
    }
    return m;
  }

 private:
  void visit(const ViewState& view, const std::string& at) {
    for (const auto& child : view.children.at(at)) {
      paths_.push_back(child);
      visit(view, child);
    }
  }
  // The id of the active state among `path`'s; -1 for a state with regions (all of them are
  // active: each region says its own) and when none is active.
  int current(const ViewState& view, const std::string& path,
              const std::vector<std::string>& kids) const {
    if (!view.is_region(path) &&
        std::any_of(kids.begin(), kids.end(), [&](const std::string& k) { return view.is_region(k); }))
      return -1;
    for (const auto& k : kids)
      if (view.active.find(k)) return ids_.at(k);
    return -1;
  }

  std::string root_name_;
  std::vector<std::string> paths_;
  std::map<std::string, int> ids_;
  std::map<std::string, std::vector<std::pair<std::string, std::string>>> outgoing_;
};

class Introspection final : public Observer {
 public:
  explicit Introspection(Node& node)
      : node_(node), name_(machine_name(node.options().node, node.options().ns)) {}

  void start(const Structure& s) override {
    view_.apply_structure(s);
    tree_.build(view_, name_, s);
    started_ = true;
  }
  void record(const Record& r) override {
    view_.apply_record(r);
    if (r.ev == "start" || r.ev == "enter" || r.ev == "exit" || r.ev == "fire" ||
        r.ev == "interrupt" || r.ev == "stop")
      changed_ = true;
  }
  void sample(long long t_ms, const std::vector<std::string>& values, long long overruns,
              double sim_rate) override {
    view_.apply_sample(t_ms, values, overruns, sim_rate);
    if (std::chrono::steady_clock::now() >= next_) publish();
  }
  void after_instant() override {
    if (changed_) publish();
  }
  void close() override { publish(); }  // the last word: the states it stopped in, and why

 private:
  void publish() {
    changed_ = false;
    next_ = std::chrono::steady_clock::now() +
            std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                std::chrono::duration<double>(kEverySeconds));
    if (!started_) return;
    std::string status = view_.snapshot_json();
    status.pop_back();  // its closing brace: `name` comes last, as the Python component puts it
    std_msgs::msg::String text;
    text.data = unescape_non_ascii(status + ",\"name\":" + json_string(name_) + "}");
    try {
      node_.publish(kMachineKey, tree_.message(view_));
      node_.publish(kStatusKey, text);
    } catch (const std::exception& e) {  // the node has left the graph (the component stops)
      if (!said_) {
        said_ = true;
        std::fprintf(stderr, "introspection: %s\n", e.what());
      }
    }
  }

  Node& node_;
  std::string name_;
  ViewState view_;
  Tree tree_;
  bool started_ = false, changed_ = false, said_ = false;
  std::chrono::steady_clock::time_point next_{};
};

// The observer of a live node, its two writers declared on it (before the node starts); a
// model's topic on one of their topics is a StartError.
inline std::unique_ptr<Observer> make(Node& node) {
  const Qos qos = Qos::profile("default");
  const std::pair<const char*, const char*> topics[] = {
      {kFsmViewer, cdr::Traits<yasmin_msgs::msg::StateMachine>::ros_type},
      {kStatus, cdr::Traits<std_msgs::msg::String>::ros_type}};
  for (const auto& [topic, type] : topics) {
    const std::string full = resolve_topic(topic, node.options().ns, node.options().node);
    for (const Node::View& v : node.views())
      if (v.topic == full)
        throw StartError("topic " + full + " is the introspection's (" + type +
                         "): the model may not subscribe or publish it");
  }
  node.advertise<yasmin_msgs::msg::StateMachine>(kMachineKey, kFsmViewer, qos);
  node.advertise<std_msgs::msg::String>(kStatusKey, kStatus, qos);
  return std::make_unique<Introspection>(node);
}

}  // namespace intro
}  // namespace ros2
}  // namespace hfsmc
