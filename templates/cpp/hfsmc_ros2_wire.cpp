// hfsmc: a Cyclone DDS 0.10 sertype of raw CDR samples (hfsmc/ros2_wire.hpp, docs/ros2-cpp.md).
//
// Cyclone asks a sertype's serdata for its serialized bytes (to send) and builds one from
// received fragments; here both are the bytes themselves. Keyless: every key operation has
// nothing to compare. The structure follows rmw_cyclonedds' serdata for serialized messages.
#include "hfsmc/ros2_wire.hpp"

#include <cstdio>
#include <cstring>
#include <new>

#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/q_radmin.h>

namespace hfsmc {
namespace ros2 {
namespace wire {
namespace {

struct Serdata : ddsi_serdata {
  std::vector<std::uint8_t> data;  // the CDR bytes, padded to a multiple of 4
};

Serdata* fresh(const ddsi_sertype* type, ddsi_serdata_kind kind) {
  auto* d = new Serdata();
  ddsi_serdata_init(d, type, kind);
  return d;
}

/// Pad to 4 and put the number of padding bytes in the options (XTypes 7.4.3.4).
void pad(Serdata* d) {
  if (d->data.size() < 4) return;
  std::size_t extra = (4 - d->data.size() % 4) % 4;
  d->data.resize(d->data.size() + extra, 0);
  d->data[3] = static_cast<std::uint8_t>((d->data[3] & ~3u) | extra);
}

bool eqkey(const ddsi_serdata*, const ddsi_serdata*) { return true; }

uint32_t get_size(const ddsi_serdata* d) {
  return static_cast<uint32_t>(static_cast<const Serdata*>(d)->data.size());
}

ddsi_serdata* from_ser(const ddsi_sertype* type, ddsi_serdata_kind kind, const nn_rdata* frag,
                       size_t size) {
  Serdata* d = fresh(type, kind);
  d->data.resize(size);
  uint32_t off = 0;
  for (; frag; frag = frag->nextfrag) {
    if (frag->maxp1 <= off) continue;  // this fragment adds nothing new
    const unsigned char* payload = NN_RMSG_PAYLOADOFF(frag->rmsg, NN_RDATA_PAYLOAD_OFF(frag));
    uint32_t end = frag->maxp1 < size ? frag->maxp1 : static_cast<uint32_t>(size);
    if (end > off) std::memcpy(d->data.data() + off, payload + (off - frag->min), end - off);
    off = frag->maxp1;
  }
  return d;
}

ddsi_serdata* from_ser_iov(const ddsi_sertype* type, ddsi_serdata_kind kind,
                           ddsrt_msg_iovlen_t niov, const ddsrt_iovec_t* iov, size_t size) {
  Serdata* d = fresh(type, kind);
  d->data.reserve(size);
  for (ddsrt_msg_iovlen_t i = 0; i < niov; ++i) {
    const auto* p = static_cast<const std::uint8_t*>(iov[i].iov_base);
    d->data.insert(d->data.end(), p, p + iov[i].iov_len);
  }
  d->data.resize(size);
  return d;
}

ddsi_serdata* from_keyhash(const ddsi_sertype* type, const ddsi_keyhash*) {
  return fresh(type, SDK_KEY);
}

ddsi_serdata* from_sample(const ddsi_sertype* type, ddsi_serdata_kind kind, const void* sample) {
  Serdata* d = fresh(type, kind);
  if (kind == SDK_DATA) {
    d->data = static_cast<const Raw*>(sample)->bytes;
    pad(d);
  }
  return d;
}

void to_ser(const ddsi_serdata* d, size_t off, size_t sz, void* buf) {
  const auto& data = static_cast<const Serdata*>(d)->data;
  std::size_t n = off < data.size() ? std::min(sz, data.size() - off) : 0;
  if (n) std::memcpy(buf, data.data() + off, n);
  if (n < sz) std::memset(static_cast<char*>(buf) + n, 0, sz - n);
}

ddsi_serdata* to_ser_ref(const ddsi_serdata* d, size_t off, size_t sz, ddsrt_iovec_t* ref) {
  const auto& data = static_cast<const Serdata*>(d)->data;
  ref->iov_base = const_cast<std::uint8_t*>(data.data()) + off;
  ref->iov_len = static_cast<decltype(ref->iov_len)>(sz);
  return ddsi_serdata_ref(d);
}

void to_ser_unref(ddsi_serdata* d, const ddsrt_iovec_t*) { ddsi_serdata_unref(d); }

/// The bytes as the sender serialized them: the padding its options announce removed.
bool to_sample(const ddsi_serdata* d, void* sample, void**, void*) {
  const auto& data = static_cast<const Serdata*>(d)->data;
  auto& out = static_cast<Raw*>(sample)->bytes;
  std::size_t n = data.size();
  if (n >= 4) {
    std::size_t extra = data[3] & 3u;
    if (extra <= n - 4) n -= extra;
  }
  out.assign(data.begin(), data.begin() + static_cast<std::ptrdiff_t>(n));
  if (n >= 4) out[2] = out[3] = 0;
  return true;
}

ddsi_serdata* to_untyped(const ddsi_serdata* d) {
  Serdata* u = fresh(d->type, SDK_KEY);
  u->type = nullptr;
  return u;
}

bool untyped_to_sample(const ddsi_sertype*, const ddsi_serdata*, void* sample, void**, void*) {
  static_cast<Raw*>(sample)->bytes.clear();
  return true;
}

void serdata_free(ddsi_serdata* d) { delete static_cast<Serdata*>(d); }

size_t print(const ddsi_sertype*, const ddsi_serdata* d, char* buf, size_t size) {
  return static_cast<size_t>(std::snprintf(buf, size, "(%zu bytes of CDR)",
                                           static_cast<const Serdata*>(d)->data.size()));
}

void get_keyhash(const ddsi_serdata*, ddsi_keyhash* buf, bool) {
  std::memset(buf, 0, sizeof(*buf));
}

// -- the sertype --------------------------------------------------------------------------
void sertype_free(ddsi_sertype* tp) {
  ddsi_sertype_fini(tp);
  delete tp;
}

void zero_samples(const ddsi_sertype*, void* samples, size_t count) {
  auto* s = static_cast<Raw*>(samples);
  for (size_t i = 0; i < count; ++i) s[i].bytes.clear();
}

void realloc_samples(void** ptrs, const ddsi_sertype*, void* old, size_t oldcount, size_t count) {
  auto* before = static_cast<Raw*>(old);
  auto* now = new Raw[count];
  for (size_t i = 0; i < oldcount && i < count; ++i) now[i] = std::move(before[i]);
  delete[] before;
  for (size_t i = 0; i < count; ++i) ptrs[i] = &now[i];
}

void free_samples(const ddsi_sertype*, void** ptrs, size_t count, dds_free_op_t op) {
  if (count == 0) return;
  if (op & DDS_FREE_ALL_BIT) {
    delete[] static_cast<Raw*>(ptrs[0]);
  } else if (op & DDS_FREE_CONTENTS_BIT) {
    for (size_t i = 0; i < count; ++i) static_cast<Raw*>(ptrs[i])->bytes.clear();
  }
}

bool equal(const ddsi_sertype*, const ddsi_sertype*) { return true; }
uint32_t hash(const ddsi_sertype*) { return 0x68667301u; }

size_t serialized_size(const ddsi_sertype*, const void* sample) {
  return static_cast<const Raw*>(sample)->bytes.size();
}

bool serialize_into(const ddsi_sertype*, const void* sample, void* dst, size_t size) {
  const auto& b = static_cast<const Raw*>(sample)->bytes;
  if (b.size() > size) return false;
  std::memcpy(dst, b.data(), b.size());
  return true;
}

ddsi_serdata_ops make_serdata_ops() {
  ddsi_serdata_ops ops;
  std::memset(&ops, 0, sizeof ops);
  ops.eqkey = eqkey;
  ops.get_size = get_size;
  ops.from_ser = from_ser;
  ops.from_ser_iov = from_ser_iov;
  ops.from_keyhash = from_keyhash;
  ops.from_sample = from_sample;
  ops.to_ser = to_ser;
  ops.to_ser_ref = to_ser_ref;
  ops.to_ser_unref = to_ser_unref;
  ops.to_sample = to_sample;
  ops.to_untyped = to_untyped;
  ops.untyped_to_sample = untyped_to_sample;
  ops.free = serdata_free;
  ops.print = print;
  ops.get_keyhash = get_keyhash;
  return ops;
}

ddsi_sertype_ops make_sertype_ops() {
  ddsi_sertype_ops ops;
  std::memset(&ops, 0, sizeof ops);
  ops.version = ddsi_sertype_v0;
  ops.free = sertype_free;
  ops.zero_samples = zero_samples;
  ops.realloc_samples = realloc_samples;
  ops.free_samples = free_samples;
  ops.equal = equal;
  ops.hash = hash;
  ops.get_serialized_size = serialized_size;
  ops.serialize_into = serialize_into;
  return ops;
}

const ddsi_serdata_ops kSerdataOps = make_serdata_ops();
const ddsi_sertype_ops kSertypeOps = make_sertype_ops();

}  // namespace

ddsi_sertype* make_sertype(const char* dds_type) {
  auto* st = new ddsi_sertype();
  ddsi_sertype_init_flags(st, dds_type, &kSertypeOps, &kSerdataOps,
                          DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  st->allowed_data_representation = DDS_DATA_REPRESENTATION_FLAG_XCDR1;
  return st;
}

}  // namespace wire
}  // namespace ros2
}  // namespace hfsmc
