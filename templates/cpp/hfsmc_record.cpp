// hfsmc_record.cpp: --record FILE and --playback DIR for C++ components (hfsmc/record.hpp
// and hfsmc/playback.hpp declare them and say how they work), compiled once into the
// library hfsmc_runtime. Copied unchanged into every component folder.
#include <sys/stat.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "hfsmc/json.hpp"
#include "hfsmc/jsonread.hpp"
#include "hfsmc/mcap.hpp"
#include "hfsmc/playback.hpp"
#include "hfsmc/record.hpp"

namespace hfsmc {

Recorder::Recorder(const std::string& path) : w_(std::make_unique<mcap::Writer>(path)) {}

Recorder::~Recorder() = default;

void Recorder::start(const Run& run) {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    start_ns_ = static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
    guard([&] {
        const auto opt = [](long long us) { return us < 0 ? std::string() : std::to_string(us); };
        w_->add_metadata("hfsmc.run", {{"recording", "1"}, {"component", run.component}, {"language", "cpp"},
                                      {"hfsmc", run.version}, {"model_hash", run.model_hash},
                                      {"clock", run.clock}, {"until_us", opt(run.until_us)},
                                      {"time_limit_us", opt(run.time_limit_us)},
                                      {"start_unix_ns", std::to_string(start_ns_)}});
        w_->add_metadata("hfsmc.parameters", run.parameters);
        mcap::Metadata interfaces;
        for (const Source* s : sources()) interfaces.emplace_back(s->source_name(), s->source_config());
        w_->add_metadata("hfsmc.interfaces", interfaces);
        w_->add_metadata("hfsmc.sources", run.sources);
        const auto schema = [&](const char* name, const char* text) {
            return w_->add_schema(name, "jsonschema", text);
        };
        const std::uint16_t mav = schema("hfsmc.mavlink.Snapshot", schemas::mavlink);
        const std::uint16_t cam = schema("hfsmc.camera.Snapshot", schemas::camera);
        const std::uint16_t img = schema("foxglove.CompressedImage", schemas::image);
        const std::uint16_t cmd = schema("hfsmc.Command", schemas::command);
        std::map<std::string, std::uint16_t> own;  // user drivers' schemas, by kind
        for (const Source* s : sources()) {
            Channels& c = channels_[s];
            const std::string type = s->source_type();
            const bool is_camera = type == "camera";
            std::uint16_t snap = is_camera ? cam : mav;
            if (type != "camera" && type != "mavlink") {
                auto found = own.find(type);
                if (found == own.end()) {
                    const std::string text = s->snapshot_schema();
                    found = own.emplace(type, schema(("hfsmc." + type + ".Snapshot").c_str(), text.c_str())).first;
                }
                snap = found->second;
            }
            c.snapshot = w_->add_channel("/hfsmc/interface/" + s->source_name(), "json", snap);
            if (is_camera) c.frame = w_->add_channel("/hfsmc/frame/" + s->source_name(), "json", img);
            c.command = w_->add_channel("/hfsmc/command/" + s->source_name(), "json", cmd);
        }
        skip_ = w_->add_channel("/hfsmc/skip", "json", schema("hfsmc.Skip", schemas::skip));
        signal_ = w_->add_channel("/hfsmc/signal", "json", schema("hfsmc.Signal", schemas::signal));
        trace_ = w_->add_channel("/hfsmc/trace", "json", schema("hfsmc.TraceRecord", schemas::trace));
        w_->flush_tick();
    });
}

void Recorder::snapshot(const Source& s, long long t) {
    write(channels_[&s].snapshot, t, "{\"t\":" + std::to_string(t) + "," + s.snapshot_fields() + "}");
    if (!broken_) s.record_raw(*this, t);
}

// A frame (its JPEG or PNG, base64) a snippet obtained first at instant t; `crc`: the CRC-32
// of its BGR pixels, row by row.
void Recorder::frame(const Source& s, long long t, long count, const char* format, const std::string& data_base64,
           std::uint32_t crc) {
    const std::uint64_t at = log_time(t);
    write(channels_[&s].frame, t,
          "{\"timestamp\":{\"sec\":" + std::to_string(at / 1000000000ULL) + ",\"nsec\":" +
              std::to_string(at % 1000000000ULL) + "},\"frame_id\":" + json_string(s.source_name()) +
              ",\"format\":\"" + format + "\",\"data\":\"" + data_base64 + "\",\"count\":" + std::to_string(count) +
              ",\"crc32\":" + std::to_string(crc) + "}");
}

void Recorder::command(const Source& s, long long t, const char* call, const std::string& args) {
    write(channels_[&s].command, t,
          "{\"t\":" + std::to_string(t) + ",\"call\":" + json_string(call) + ",\"args\":" + args + "}");
}

void Recorder::raw(const Source& s, long long t, const RawChannel& channel, const std::uint8_t* data,
                   std::size_t size) {
    guard([&] {
        const auto key = std::make_pair(&s, channel.key);
        auto found = raw_.find(key);
        if (found == raw_.end()) {
            const std::string kind = channel.schema_encoding + std::string(1, '\0') + channel.schema;
            auto schema = raw_schemas_.find(kind);
            if (schema == raw_schemas_.end())
                schema = raw_schemas_.emplace(kind, w_->add_schema(channel.schema, channel.schema_encoding,
                                                                   channel.schema_data)).first;
            found = raw_.emplace(key, w_->add_channel(channel.topic, channel.encoding, schema->second,
                                                      channel.metadata)).first;
        }
        const std::uint64_t at = log_time(t);
        w_->write(found->second, at, at, data, size);
    });
}

void Recorder::skip(long long t, const std::string& automaton, long long deadline, long long missed) {
    write(skip_, t, "{\"t\":" + std::to_string(t) + ",\"automaton\":" + json_string(automaton) +
                        ",\"deadline\":" + std::to_string(deadline) + ",\"missed\":" + std::to_string(missed) + "}");
}

void Recorder::signal(long long t, const std::string& reason, long long ticks) {
    write(signal_, t, "{\"t\":" + std::to_string(t) + ",\"reason\":" + json_string(reason) +
                          ",\"ticks\":" + std::to_string(ticks) + "}");
}
// A trace record (its line without the newline) at logical time t (us).
void Recorder::trace(long long t, const std::string& record) { write(trace_, t, record); }


void Recorder::flush_tick() {
    guard([&] { w_->flush_tick(); });
}

void Recorder::close() {
    guard([&] { w_->close(); });
}

void Recorder::write(std::uint16_t channel, long long t, const std::string& payload) {
    guard([&] { w_->write(channel, log_time(t), payload); });
}

namespace playback {

Inputs::Inputs(const std::string& dir) : dir_(dir.empty() ? "." : dir) {
    path_ = dir_ + "/inputs.jsonl";
    std::FILE* f = std::fopen(path_.c_str(), "rb");
    if (f == nullptr) throw InputError(path_ + ": " + std::strerror(errno));
    std::string text;
    char buf[65536];
    std::size_t got;
    while ((got = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, got);
    const int failed = std::ferror(f) ? errno : 0;
    std::fclose(f);
    if (failed) throw InputError(path_ + ": " + std::strerror(failed));
    int line = 0;
    long long last_t = 0;
    for (std::size_t at = 0; at < text.size();) {
        std::size_t nl = text.find('\n', at);
        if (nl == std::string::npos) nl = text.size();
        ++line;
        const std::string row = text.substr(at, nl - at);
        at = nl + 1;
        if (row.find_first_not_of(" \t\r") == std::string::npos) continue;
        json::Value v;
        try {
            v = json::Reader::parse(row);
        } catch (const std::exception& e) {
            throw InputError(where(line) + ": not JSON: " + e.what());
        }
        if (v.kind != json::Value::OBJECT) throw InputError(where(line) + ": expected a JSON object");
        const long long t = integer(v, "t", line);
        if (t < last_t) throw InputError(where(line) + ": `t` goes back in time (" +
                                         std::to_string(t) + " after " + std::to_string(last_t) + ")");
        last_t = t;
        const std::string kind = text_of(v, "kind", line);
        if (kind == "snapshot") {
            const std::string iface = text_of(v, "interface", line);
            const json::Value* values = v.get("values");
            if (values == nullptr || values->kind != json::Value::OBJECT)
                throw InputError(where(line) + ": `values` must be an object");
            Entry e{t, line, *values, {}};
            if (const json::Value* missing = v.get("unrecorded")) {
                if (missing->kind != json::Value::ARRAY)
                    throw InputError(where(line) + ": `unrecorded` must be a list of field names");
                for (const json::Value& m : missing->items) e.unrecorded.push_back(Inputs::text(m, "unrecorded", line));
            }
            by_interface_[iface].push_back(std::move(e));
        } else if (kind == "skip") {
            skips_.push_back({t, line, text_of(v, "automaton", line), integer(v, "deadline", line),
                              integer(v, "missed", line)});
        } else if (kind == "signal") {
            Signal s{t, line, text_of(v, "reason", line), integer(v, "ticks", line)};
            if (s.reason != "sigint" && s.reason != "sigterm" && s.reason != "time_limit")
                throw InputError(where(line) + ": `reason` must be sigint, sigterm or time_limit, not " +
                                 json_string(s.reason));
            signals_.push_back(s);
        } else if (kind == "recorded") {
            recorded_ = true;
        } else {
            throw InputError(where(line) + ": unknown kind " + json_string(kind) +
                             " (kinds: snapshot, skip, signal, recorded)");
        }
    }
    const std::string out = dir_ + "/commands.jsonl";
    commands_ = std::fopen(out.c_str(), "wb");  // this run's commands only
    if (commands_ == nullptr) throw InputError(out + ": " + std::strerror(errno));
}

Inputs::~Inputs() {
    if (commands_ != nullptr) std::fclose(commands_);
}

// A command an interface was given: one line of DIR/commands.jsonl, on disk at once.
void Inputs::command(long long t, const std::string& iface, const char* call, const std::string& args) {
    const std::string line = "{\"t\":" + std::to_string(t) + ",\"interface\":" + json_string(iface) +
                             ",\"call\":" + json_string(call) + ",\"args\":" + args + "}\n";
    if (std::fwrite(line.data(), 1, line.size(), commands_) != line.size() || std::fflush(commands_) != 0) {
        if (!broken_)
            std::fprintf(stderr, "playback: cannot write to %s/commands.jsonl: %s\n", dir_.c_str(),
                         std::strerror(errno));
        broken_ = true;
    }
}

// A query the inputs cannot answer: the first one goes to DIR/unanswered.jsonl.
void Inputs::unanswered(long long t, const std::string& iface, const char* query, const std::string& reason,
                        long long count) {
    if (!answered_all_) return;
    answered_all_ = false;
    std::string line = "{\"t\":" + std::to_string(t) + ",\"interface\":" + json_string(iface) +
                       ",\"query\":" + json_string(query) + ",\"reason\":" + json_string(reason);
    if (count >= 0) line += ",\"count\":" + std::to_string(count);
    line += "}\n";
    const std::string out = dir_ + "/unanswered.jsonl";
    std::FILE* f = std::fopen(out.c_str(), "wb");
    if (f == nullptr || std::fwrite(line.data(), 1, line.size(), f) != line.size()) {
        std::fprintf(stderr, "playback: cannot write %s: %s\n", out.c_str(), std::strerror(errno));
    }
    if (f != nullptr) std::fclose(f);
}

}  // namespace playback

}  // namespace hfsmc
