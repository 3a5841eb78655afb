// hfsmc/driver.hpp: the base of a C++ driver (`type: driver`, docs/drivers.md), the
// built-in `mavlink` and `camera` drivers' too. Copied into a C++ component whose model
// names a driver of its own, or the camera or a mavlink vehicle.
//
// The C++ twin of templates/python/hfsmc_driver.py. A driver derives from
// hfsmc::Driver<Snap>, where Snap is a plain struct of the snapshot's fields with their
// "nothing yet" values and a static `fields(Snap&)` that names them (in the order of the
// declaration block); the base class then takes the snapshot of each instant (live:
// read(); with --playback: the script's entries), records it (channel
// /hfsmc/interface/NAME, schema hfsmc.KIND.Snapshot, the same JSON as the Python
// driver's), tells every command to the recording or the playback, and keeps the
// options (the declared defaults under the model's and NAME.yaml's values).
//
// A field is a double, a long long, a bool or a std::string, or one of the typed kinds:
// Numbers (a fixed array of doubles: an Eigen::Vector3d's data(); JSON [x, y, z]),
// Wholes (a fixed array of whole numbers: [current, total]) and Texts (a map of names to
// texts: the acks of commands; a JSON object, which a script's entry replaces whole).
//
// A query reads snap("query"); a command starts with `if (!command("name", args_json))
// return;` (a fake sends nothing). A command that checks its arguments and runs in a fake
// too (what it calls to send does nothing there) tells them with tell(), and may change
// the instant's snapshot until the next one with instant() (a pending ack). The driver's
// own thread: start_thread(), which loops until stopping(); its destructor calls stop()
// first (the thread must end before the members it uses go).
//
// Hooks a Snap may declare beside `fields` (the built-in camera's, hfsmc/camera.hpp):
//   static bool extra(Snap&, const std::string& key, const json::Value&, int line,
//                     const playback::Inputs&)  a script's key beside the fields (the
//       camera's `frame` file and `crc32`): true when taken; a bad value throws InputError
//       (returning true for every key ignores what the driver does not know: mavlink);
//   static long long frame_number(const Snap&)  the number of the instant's image, which a
//       replay notes with a frame the recording lacks.
// And a driver may be made with Policy (options it does not know ignored, or all of them
// kept as given for it to read and say itself; no fields table in the live views when it
// shows something else: it is a Feed of its own) and override snapshot_taken(),
// stop_warning() (what warning_at_stop() says when the component stops with the device
// busy: the vehicle still armed) and simclock::Synced's lockstep_sent() and
// lockstep_sync() once it has joined `hfsmc sim`'s lockstep with join_lockstep().
#pragma once

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "hfsmc/json.hpp"
#include "hfsmc/observer.hpp"
#include "hfsmc/playback.hpp"
#include "hfsmc/record.hpp"
#include "hfsmc/simclock.hpp"
#include "hfsmc/thread.hpp"

namespace hfsmc {

// A fixed array of numbers in a Snap (an Eigen::Vector3d's data()): a JSON array of `n`
// numbers; `shape` names its items in a script's error ("[x, y, z]").
struct Numbers {
    double* at;
    int n;
    const char* shape = nullptr;
};
// A fixed array of whole numbers (a mission's [current, total]).
struct Wholes {
    long long* at;
    int n;
    const char* shape = nullptr;
};
// A map of names to texts (the acks of commands): a JSON object.
using Texts = std::map<std::string, std::string>;

// One snapshot field: its name and where it lives in a Snap.
struct Field {
    const char* name;
    std::variant<double*, long long*, bool*, std::string*, Numbers, Wholes, Texts*> ref;
};

namespace detail {
template <class S, class = void>
struct has_extra : std::false_type {};
template <class S>
struct has_extra<S, std::void_t<decltype(S::extra(std::declval<S&>(), std::declval<const std::string&>(),
                                                  std::declval<const json::Value&>(), 0,
                                                  std::declval<const playback::Inputs&>()))>>
    : std::true_type {};
template <class S, class = void>
struct has_frame_number : std::false_type {};
template <class S>
struct has_frame_number<S, std::void_t<decltype(S::frame_number(std::declval<const S&>()))>>
    : std::true_type {};

// A field's value as the recording has it (the Python driver's JSON).
inline std::string field_json(const Field& f) {
    if (auto d = std::get_if<double*>(&f.ref)) return json_number(**d);
    if (auto i = std::get_if<long long*>(&f.ref)) return std::to_string(**i);
    if (auto b = std::get_if<bool*>(&f.ref)) return **b ? "true" : "false";
    if (auto s = std::get_if<std::string*>(&f.ref)) return json_string(**s);
    std::string out;
    if (auto a = std::get_if<Numbers>(&f.ref)) {
        for (int k = 0; k < a->n; ++k) out += (k == 0 ? "" : ",") + json_number(a->at[k]);
        return "[" + out + "]";
    }
    if (auto w = std::get_if<Wholes>(&f.ref)) {
        for (int k = 0; k < w->n; ++k) out += (k == 0 ? "" : ",") + std::to_string(w->at[k]);
        return "[" + out + "]";
    }
    for (const auto& kv : *std::get<Texts*>(f.ref))
        out += (out.empty() ? "" : ",") + json_string(kv.first) + ":" + json_string(kv.second);
    return "{" + out + "}";
}

// A field's JSON Schema, as the Python driver's snapshot_schema() gives it.
inline std::string field_schema(const Field& f) {
    if (std::holds_alternative<double*>(f.ref)) return "{\"type\": [\"number\", \"string\"]}";
    if (std::holds_alternative<long long*>(f.ref)) return "{\"type\": \"integer\"}";
    if (std::holds_alternative<bool*>(f.ref)) return "{\"type\": \"boolean\"}";
    if (std::holds_alternative<std::string*>(f.ref)) return "{\"type\": [\"string\", \"null\"]}";
    if (std::holds_alternative<Texts*>(f.ref)) return "{}";
    return "{\"type\": \"array\"}";
}

// A script's value over a field; a bad one throws InputError at `line`.
inline void field_apply(const Field& f, const json::Value& v, int line, const playback::Inputs& in) {
    const auto items = [&](int n, const char* shape, const char* of) {
        if (v.kind != json::Value::ARRAY || v.items.size() != static_cast<std::size_t>(n))
            in.bad(line, "`" + std::string(f.name) + "` must be " +
                             (shape != nullptr ? std::string(shape) : "an array of " + std::to_string(n) + of));
    };
    if (auto d = std::get_if<double*>(&f.ref)) {
        **d = in.number(v, f.name, line);
    } else if (auto i = std::get_if<long long*>(&f.ref)) {
        **i = in.whole(v, f.name, line);
    } else if (auto b = std::get_if<bool*>(&f.ref)) {
        **b = in.boolean(v, f.name, line);
    } else if (auto s = std::get_if<std::string*>(&f.ref)) {
        **s = in.text(v, f.name, line);
    } else if (auto a = std::get_if<Numbers>(&f.ref)) {
        items(a->n, a->shape, " numbers");
        for (int k = 0; k < a->n; ++k) a->at[k] = in.number(v.items[k], f.name, line);
    } else if (auto w = std::get_if<Wholes>(&f.ref)) {
        items(w->n, w->shape, " integers");
        for (int k = 0; k < w->n; ++k) w->at[k] = in.whole(v.items[k], f.name, line);
    } else {
        if (v.kind != json::Value::OBJECT) in.bad(line, "`" + std::string(f.name) + "` must be an object");
        Texts& m = *std::get<Texts*>(f.ref);
        m.clear();
        for (const auto& kv : v.members) m[kv.first] = in.text(kv.second, f.name, line);
    }
}
}  // namespace detail

// How a driver is made beyond its declaration.
struct Policy {
    bool ignore_unknown_options = false;  // the driver says them itself (the camera)
    bool fields_view = true;  // the live views show the fields (false: the driver feeds its own)
    // The options as given, neither checked nor merged with the declared defaults: the
    // driver reads them, says a bad or unknown one and goes on (mavlink); recorded so.
    bool own_options = false;
};

template <class Snap>
class Driver : public Source, public simclock::Synced {
public:
    using Options = std::map<std::string, std::string>;

    // `kind`: the declaration's kind; `declared`: each option and its default, as text.
    Driver(const char* kind, std::string name, std::string url, const Options& options,
           const Options& declared, Policy policy = Policy())
        : kind_(kind), name_(std::move(name)), url_(std::move(url)),
          options_(policy.own_options ? options : declared) {
        for (const auto& kv : options) {
            if (policy.own_options) break;
            if (declared.count(kv.first) == 0 && policy.ignore_unknown_options) continue;
            if (declared.count(kv.first) == 0) {
                std::string known;
                for (const auto& d : declared) known += (known.empty() ? "" : ", ") + d.first;
                say("cannot start: no option `" + kv.first + "` (options: " +
                    (known.empty() ? "none" : known) + ")");
                std::exit(1);
            }
            options_[kv.first] = kv.second;
        }
        if (playback::Inputs* inputs = playback::current()) {  // a fake fed from the inputs
            inputs_ = inputs;
            Snap scratch;  // every entry checked now: a bad value is said before the run
            for (const playback::Entry& e : inputs->entries(name_)) apply(scratch, e);
        }
        register_source(this);
        if (policy.fields_view) view_.start(inputs_ == nullptr);
    }
    ~Driver() override {
        leave_lockstep();
        unregister_source(this);
        stop();
    }
    Driver(const Driver&) = delete;
    Driver& operator=(const Driver&) = delete;

    const std::string& name() const { return name_; }
    const std::string& url() const { return url_; }

    // What the component says when it stops with the device left busy (the runtime calls
    // it, a snippet may too; no replay notes it as a question): stop_warning(), "" for none.
    std::string warning_at_stop() const {
        evidence_.quiet(true);
        struct Loud {
            const playback::Evidence& e;
            ~Loud() { e.quiet(false); }
        } loud{evidence_};
        return stop_warning();
    }

    // -- simclock::Synced: nothing to wait for unless the driver has joined the lockstep --
    long long lockstep_sent() const override { return 0; }
    std::string lockstep_sync(long long /*t_us*/, const simclock::Step& /*step*/) override {
        return std::string();
    }

    // -- Source: the snapshot of each instant -------------------------------------------
    const std::string& source_name() const override { return name_; }
    const char* source_type() const override { return kind_; }
    std::string source_config() const override {
        std::string options;
        for (const auto& kv : options_)
            options += (options.empty() ? "" : ",") + json_string(kv.first) + ":" + json_string(kv.second);
        return "{\"type\":" + json_string(kind_) + ",\"url\":" + json_string(url_) + ",\"options\":{" +
               options + "}}";
    }
    void take_snapshot(long long t_us) override {
        snapshot_t_ = t_us;
        if (inputs_ == nullptr) {
            Snap latest = snap_;
            read(latest);
            snap_ = latest;
            view_.set(snap_);
            snapshot_taken();
            return;
        }
        const std::vector<playback::Entry>& entries = inputs_->entries(name_);
        for (; next_ < entries.size() && entries[next_].t <= t_us; ++next_) apply(fed_, entries[next_]);
        snap_ = fed_;
        view_.set(snap_);
        long long number = -1;
        if constexpr (detail::has_frame_number<Snap>::value) number = Snap::frame_number(snap_);
        evidence_.at(inputs_, name_, t_us, next_ > 0 ? &entries[next_ - 1] : nullptr, number);
        snapshot_taken();
    }
    std::string snapshot_fields() const override {
        Snap s = snap_;
        std::string out;
        for (const Field& f : Snap::fields(s))
            out += (out.empty() ? "\"" : ",\"") + std::string(f.name) + "\":" + detail::field_json(f);
        return out;
    }
    // The JSON Schema of the recorded snapshot: the text the Python driver's recording has.
    std::string snapshot_schema() const override {
        Snap s;
        std::string props = "\"t\": {\"type\": \"integer\"}";
        for (const Field& f : Snap::fields(s))
            props += ", \"" + std::string(f.name) + "\": " + detail::field_schema(f);
        return "{\"title\": \"What the automaton saw of a " + std::string(kind_) +
               " during one instant\", \"type\": \"object\", \"properties\": {" + props + "}}";
    }

protected:
    // Live only: overwrite in `latest` what the device said since (called from the
    // automaton's thread once per instant: guard what the driver's thread shares).
    virtual void read(Snap& latest) = 0;

    // After each instant's snapshot (live or fed): what the driver derives from it.
    virtual void snapshot_taken() {}

    // What warning_at_stop() says (the instant's snapshot at hand: current()); "": none.
    virtual std::string stop_warning() const { return std::string(); }

    bool live() const { return inputs_ == nullptr; }
    // The instant's snapshot, for query `query` (a playback notes what it cannot answer),
    // which reads `field` (by default the field of the query's name; "frame": the image).
    const Snap& snap(const char* query, const char* field = nullptr) const {
        evidence_.asked(query, field != nullptr ? field : query);
        return snap_;
    }
    // The instant's snapshot, for the driver's own use (no query).
    const Snap& current() const { return snap_; }
    // The instant's snapshot, which a command changes until the next instant (live and
    // fed alike: a pending ack).
    Snap& instant() { return snap_; }
    // A command: told to the recording (or the playback); false when it must not be sent.
    bool command(const char* call, const std::string& args_json) {
        tell(call, args_json);
        return live();
    }
    // A command that checked its own arguments: told to the recording (or the playback)
    // as they are; what it then sends is the driver's (nothing when !live()).
    void tell(const char* call, const std::string& args_json) { sent(call, args_json); }
    // One line on stderr, `NAME: text`, in one write (lines of two threads never mix).
    void say(const std::string& text) const {
        const std::string line = name_ + ": " + text + "\n";
        std::fwrite(line.data(), 1, line.size(), stderr);
        std::fflush(stderr);
    }
    void start_thread(std::function<void()> fn) { threads_.push_back(quiet_thread(std::move(fn))); }
    bool stopping() const { return stop_.load(); }
    // End the driver's threads; the derived destructor calls it first.
    void stop() {
        stop_ = true;
        for (std::thread& t : threads_)
            if (t.joinable()) t.join();
        threads_.clear();
    }
    // --clock sim, live: join `hfsmc sim`'s lockstep (before each instant the clock calls
    // lockstep_sync(), which waits, bounded, for what the simulator says it sent); the
    // simulator's clock, or nullptr on the wall clock. The base leaves it when it goes.
    simclock::Client* join_lockstep() {
        if (lockstep_ == nullptr && live() && simclock::current() != nullptr) {
            lockstep_ = simclock::current();
            lockstep_->add(this);
        }
        return lockstep_;
    }
    // Leave the lockstep (a derived destructor may, first).
    void leave_lockstep() {
        if (lockstep_ != nullptr && simclock::current() == lockstep_) lockstep_->remove(this);
        lockstep_ = nullptr;
    }
    // The options: the declared ones with the model's values, or (Policy::own_options) as given.
    const Options& options() const { return options_; }
    const std::string& option(const std::string& key) const { return options_.at(key); }
    double option_number(const std::string& key) const { return std::stod(option(key)); }
    // The names an option lists ("scan, odom", "[scan, odom]").
    std::vector<std::string> option_names(const std::string& key) const {
        std::vector<std::string> out;
        std::string word;
        for (char c : option(key) + " ") {
            if (c == ' ' || c == ',' || c == '[' || c == ']' || c == '\'' || c == '"') {
                if (!word.empty()) out.push_back(word);
                word.clear();
            } else {
                word += c;
            }
        }
        return out;
    }
    // A name argument that must be one the option lists: std::invalid_argument otherwise.
    void check_name(const char* method, const std::string& key, const std::string& given) const {
        std::string listed;
        for (const std::string& n : option_names(key)) {
            if (n == given) return;
            listed += (listed.empty() ? "" : ", ") + n;
        }
        throw std::invalid_argument(name_ + "." + method + ": `" + given + "` is not one of " + key + ": " +
                                    (listed.empty() ? "none" : listed));
    }

private:
    void apply(Snap& s, const playback::Entry& e) const {
        std::vector<Field> fields = Snap::fields(s);
        for (const auto& m : e.values.members) {
            const Field* f = nullptr;
            for (const Field& x : fields)
                if (m.first == x.name) f = &x;
            if constexpr (detail::has_extra<Snap>::value) {
                if (f == nullptr && Snap::extra(s, m.first, m.second, e.line, *inputs_)) continue;
            }
            if (f == nullptr) inputs_->bad(e.line, "the " + std::string(kind_) + " interface `" + name_ +
                                                       "` has no snapshot field `" + m.first + "`");
            detail::field_apply(*f, m.second, e.line, *inputs_);
        }
    }

    // The live views (schemas/monitor.md, minor version 4): the latest instant's snapshot,
    // copied for the monitor's thread once a viewer has asked (nothing is copied before),
    // sent as field/value pairs. A Feed of its own, unregistered when it goes, first of
    // the driver's members (the monitor then never sees a driver half gone).
    class View final : public Feed {
    public:
        View(const char* kind, const std::string& name) : kind_(kind), name_(name) {}
        ~View() override {
            if (started_) unregister_feed(this);
        }
        View(const View&) = delete;
        View& operator=(const View&) = delete;
        void start(bool live) {
            live_ = live;
            started_ = true;
            register_feed(this);
        }
        void set(const Snap& s) {
            if (!watched_.load(std::memory_order_relaxed)) return;
            std::lock_guard<std::mutex> lock(m_);
            shown_ = s;
            has_ = true;
        }
        const char* feed_kind() const override { return "driver"; }
        std::string feed_name() const override { return name_; }
        std::string feed_message(long long t_ms) override {
            watched_ = true;
            Snap s;
            {
                std::lock_guard<std::mutex> lock(m_);
                if (!has_) return "";
                s = shown_;
            }
            std::string fields;
            for (const Field& f : Snap::fields(s)) {
                fields += std::string(fields.empty() ? "" : ",") + "{\"name\":" + json_string(f.name) +
                          ",\"value\":";
                if (auto d = std::get_if<double*>(&f.ref)) fields += number(**d);
                else if (auto i = std::get_if<long long*>(&f.ref))
                    fields += (**i < (1LL << 53) && **i > -(1LL << 53)) ? std::to_string(**i)
                                                                         : json_string(std::to_string(**i));
                else if (auto b = std::get_if<bool*>(&f.ref)) fields += **b ? "true" : "false";
                else if (auto s = std::get_if<std::string*>(&f.ref)) fields += json_string(cut(**s));
                else fields += json_string(cut(printed(f)));
                fields += "}";
            }
            return "{\"type\":\"driver\",\"t\":" + std::to_string(t_ms) + ",\"name\":" + json_string(name_) +
                   ",\"kind\":" + json_string(kind_) + ",\"live\":" + (live_ ? "true" : "false") +
                   ",\"fields\":[" + fields + "]}";
        }

    private:
        // 6 significant digits, as the Python monitor sends them; inf, -inf, nan as text.
        static std::string number(double v) {
            if (!std::isfinite(v)) return "\"" + float_repr(v) + "\"";
            char b[32];
            std::snprintf(b, sizeof b, "%.6g", v);
            return b;
        }
        // A list or a map as Python prints the shown values: [1.5, nan, 3], {'arm': 'accepted'}.
        static std::string printed(const Field& f) {
            std::string out;
            if (auto a = std::get_if<Numbers>(&f.ref)) {
                for (int k = 0; k < a->n; ++k) {
                    const double v = a->at[k];
                    out += (k == 0 ? "" : ", ") + (std::isfinite(v) ? float_repr(std::stod(number(v))) : float_repr(v));
                }
                return "[" + out + "]";
            }
            if (auto w = std::get_if<Wholes>(&f.ref)) {
                for (int k = 0; k < w->n; ++k) out += (k == 0 ? "" : ", ") + std::to_string(w->at[k]);
                return "[" + out + "]";
            }
            for (const auto& kv : *std::get<Texts*>(f.ref))
                out += (out.empty() ? "" : ", ") + string_repr(kv.first) + ": " + string_repr(kv.second);
            return "{" + out + "}";
        }
        // At most 80 characters (code points): longer ends with an ellipsis.
        static std::string cut(const std::string& text) {
            std::size_t points = 0;
            for (std::size_t i = 0; i < text.size(); ++i) {
                if ((static_cast<unsigned char>(text[i]) & 0xC0) == 0x80) continue;
                if (++points == 80) {
                    std::size_t rest = 0;
                    for (std::size_t j = i; j < text.size(); ++j)
                        rest += (static_cast<unsigned char>(text[j]) & 0xC0) != 0x80;
                    return rest > 1 ? text.substr(0, i) + "\u2026" : text;
                }
            }
            return text;
        }

        const char* kind_;
        std::string name_;
        bool live_ = true, started_ = false;
        std::mutex m_;
        Snap shown_{};
        bool has_ = false;
        std::atomic<bool> watched_{false};
    };

    const char* kind_;
    std::string name_, url_;
    Options options_;
    Snap snap_{}, fed_{};
    playback::Inputs* inputs_ = nullptr;
    std::size_t next_ = 0;
    playback::Evidence evidence_;
    std::atomic<bool> stop_{false};
    std::vector<std::thread> threads_;
    simclock::Client* lockstep_ = nullptr;  // joined with join_lockstep()
    View view_{kind_, name_};  // last: gone first
};

}  // namespace hfsmc
