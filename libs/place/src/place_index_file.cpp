// place_index.bin: a little-endian binary file, CRC-32 at the end (docs/place-index.md).
#include <zlib.h>

#include <mrpt/config/CConfigFileMemory.h>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/reference_database.h"
#include "place_index_impl.h"

namespace lookup::place {

namespace {

constexpr char kMagic[8] = {'L', 'K', 'U', 'P', 'P', 'L', 'C', 'E'};
// 2: features detected on the illumination-free image (illumination_sigma_px); 3: a noisy
// image smoothed first (noisy_*). Older files are still read, as they were built.
constexpr std::uint32_t kFormatVersion = 3;

class Writer {
  public:
    template <typename T>
    void put(const T& v) {
        bytes_.append(reinterpret_cast<const char*>(&v), sizeof v);
    }
    void putBytes(const void* data, std::size_t n) {
        bytes_.append(static_cast<const char*>(data), n);
    }
    void putString(const std::string& s) {
        put(static_cast<std::uint32_t>(s.size()));
        putBytes(s.data(), s.size());
    }
    std::string finish() {
        const auto crc = static_cast<std::uint32_t>(crc32(
            0L, reinterpret_cast<const Bytef*>(bytes_.data()), static_cast<uInt>(bytes_.size())));
        put(crc);
        return std::move(bytes_);
    }

  private:
    std::string bytes_;
};

class Reader {
  public:
    Reader(std::string bytes, std::string path)
        : bytes_(std::move(bytes)), path_(std::move(path)) {}
    template <typename T>
    T get() {
        T v;
        getBytes(&v, sizeof v);
        return v;
    }
    void getBytes(void* out, std::size_t n) {
        if (n > bytes_.size() - pos_) fail("truncated");
        std::memcpy(out, bytes_.data() + pos_, n);
        pos_ += n;
    }
    std::string getString() {
        const auto n = get<std::uint32_t>();
        if (n > bytes_.size() - pos_) fail("truncated");
        std::string s = bytes_.substr(pos_, n);
        pos_ += n;
        return s;
    }
    [[noreturn]] void fail(const std::string& why) const {
        throw PlaceIndexError(path_ + ": " + why + " (rebuild it: lookup-place --db DIR)");
    }
    std::size_t remaining() const { return bytes_.size() - pos_; }

  private:
    std::string bytes_;
    std::string path_;
    std::size_t pos_ = 0;
};

std::string readWholeFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw PlaceIndexError(path + ": cannot open the place index");
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Checks the trailing CRC-32 and strips it.
std::string verifiedPayload(std::string bytes, const std::string& path) {
    if (bytes.size() < sizeof kMagic + 4 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) {
        throw PlaceIndexError(path +
                              ": not a LookUP place index (rebuild it: lookup-place --db DIR)");
    }
    std::uint32_t stored;
    std::memcpy(&stored, bytes.data() + bytes.size() - 4, 4);
    bytes.resize(bytes.size() - 4);
    const auto crc = static_cast<std::uint32_t>(
        crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size())));
    if (crc != stored) {
        throw PlaceIndexError(path +
                              ": corrupt or truncated (CRC-32 mismatch; rebuild it: lookup-place "
                              "--db DIR)");
    }
    return bytes;
}

}  // namespace

void PlaceIndex::save(const std::string& path) const {
    const detail::Impl& impl = *impl_;
    Writer w;
    w.putBytes(kMagic, sizeof kMagic);
    w.put(kFormatVersion);
    w.put(impl.fingerprint);
    w.put(static_cast<std::uint64_t>(impl.database_references));
    w.put(static_cast<std::uint64_t>(impl.indexed_references));
    mrpt::config::CConfigFileMemory options;
    impl.options.saveToConfigFile(options, "place_index");
    std::string options_text;
    options.getContent(options_text);
    w.putString(options_text);
    w.put(static_cast<std::uint64_t>(impl.features.size()));
    w.put(static_cast<std::int32_t>(impl.descriptors.cols));
    w.put(static_cast<std::int32_t>(impl.descriptors.type()));
    w.putBytes(impl.features.data(), impl.features.size() * sizeof(detail::Feature));
    if (!impl.descriptors.empty()) {
        w.putBytes(impl.descriptors.data, impl.descriptors.total() * impl.descriptors.elemSize());
    }
    common::writeFileAtomically(path, w.finish());
}

PlaceIndex PlaceIndex::load(const std::string& path, const database::ReferenceDatabase& db,
                            const PlaceIndexOptions& query) {
    Reader r(verifiedPayload(readWholeFile(path), path), path);
    char magic[sizeof kMagic];
    r.getBytes(magic, sizeof magic);
    const auto version = r.get<std::uint32_t>();
    if (version < 1 || version > kFormatVersion) {
        r.fail("format version " + std::to_string(version) + ", this program reads 1 to " +
               std::to_string(kFormatVersion));
    }
    query.check();
    PlaceIndex index;
    detail::Impl& impl = *index.impl_;
    impl.fingerprint = r.get<std::uint64_t>();
    impl.database_references = r.get<std::uint64_t>();
    impl.indexed_references = r.get<std::uint64_t>();
    if (impl.fingerprint != referenceFingerprint(db) || impl.database_references != db.size()) {
        r.fail("built for another database (" + std::to_string(impl.database_references) +
               " references, this one has " + std::to_string(db.size()) + " or other poses)");
    }
    // Build options from the file, query options from the caller.
    const common::NamedConfigFile stored(r.getString(), path);
    PlaceIndexOptions built;
    common::loadAndCheck(built, stored, "place_index");
    impl.options = query;
    impl.options.features = built.features;
    impl.options.features_per_reference = built.features_per_reference;
    impl.options.reference_spacing_m = built.reference_spacing_m;
    impl.options.illumination_sigma_px = version == 1 ? 0.0 : built.illumination_sigma_px;
    impl.options.noisy_texture_to_noise = version < 3 ? 0.0 : built.noisy_texture_to_noise;
    impl.options.noisy_blur_sigma_px = built.noisy_blur_sigma_px;
    impl.options.noisy_max_gain = built.noisy_max_gain;
    const auto n = r.get<std::uint64_t>();
    const auto cols = r.get<std::int32_t>();
    const auto type = r.get<std::int32_t>();
    const std::size_t elem = CV_ELEM_SIZE(type);
    if (cols < 0 || cols > 4096 || (n > 0 && (elem == 0 || cols == 0)) ||
        n > r.remaining() /
                (sizeof(detail::Feature) + std::size_t(cols) * std::max<std::size_t>(elem, 1))) {
        r.fail("inconsistent feature table");
    }
    impl.features.resize(n);
    r.getBytes(impl.features.data(), n * sizeof(detail::Feature));
    for (const auto& f : impl.features) {
        if (f.reference >= db.size())
            r.fail("a feature names reference " + std::to_string(f.reference));
    }
    if (n > 0) {
        impl.descriptors.create(static_cast<int>(n), cols, type);
        r.getBytes(impl.descriptors.data, impl.descriptors.total() * impl.descriptors.elemSize());
    }
    if (r.remaining() != 0) r.fail("trailing bytes");
    detail::buildSearch(impl);
    return index;
}

bool PlaceIndex::existsFor(const database::ReferenceDatabase& db) {
    return std::filesystem::exists(db.directory() + "/" + kPlaceIndexFile);
}

}  // namespace lookup::place
