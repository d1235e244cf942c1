#include "lookup/database/manifest.h"

#include <zlib.h>

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "lookup/common/errors.h"
#include "lookup/database/reference.h"

namespace lookup::database {
namespace fs = std::filesystem;
namespace {

struct Digest {
    uLong crc = crc32(0L, Z_NULL, 0);
    std::uintmax_t size = 0;
    void add(const char* data, std::size_t n) {
        crc = crc32(crc, reinterpret_cast<const Bytef*>(data), static_cast<uInt>(n));
        size += n;
    }
};

// db.ini without its [heatmaps] section (lookup-train rewrites that one).
Digest dbIniDigest(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    Digest d;
    bool heatmaps = false;
    for (std::string line; std::getline(in, line);) {
        const auto b = line.find_first_not_of(" \t\r");
        if (b != std::string::npos && line[b] == '[')
            heatmaps = line.compare(b, 10, "[heatmaps]") == 0;
        if (heatmaps) continue;
        line += '\n';
        d.add(line.data(), line.size());
    }
    return d;
}

Digest digestOf(const fs::path& path, const std::string& relative) {
    if (relative == kDbIni) return dbIniDigest(path);
    std::ifstream in(path, std::ios::binary);
    Digest d;
    std::vector<char> buf(1 << 16);
    while (in) {
        in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
        d.add(buf.data(), static_cast<std::size_t>(in.gcount()));
    }
    return d;
}

}  // namespace

void writeManifest(const std::string& dir) {
    std::vector<std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (!e.is_regular_file()) continue;
        const std::string rel = fs::relative(e.path(), dir).generic_string();
        if (rel != kManifest) files.push_back(rel);
    }
    std::sort(files.begin(), files.end());
    const std::string path = dir + "/" + kManifest;
    std::ofstream out(path);
    out << "# LookUP database checksums: CRC-32 (zlib), size [bytes], file; db.ini without "
           "[heatmaps]\n";
    for (const auto& rel : files) {
        const Digest d = digestOf(fs::path(dir) / rel, rel);
        char line[64];
        std::snprintf(line, sizeof(line), "%08lx %ju ", static_cast<unsigned long>(d.crc), d.size);
        out << line << rel << "\n";
    }
    out.close();
    if (!out) throw common::WriteError(path, "cannot write");
}

bool verifyManifest(const std::string& dir) {
    const fs::path path = fs::path(dir) / kManifest;
    if (!fs::exists(path)) return false;
    std::ifstream in(path);
    std::size_t number = 0;
    for (std::string line; std::getline(in, line);) {
        ++number;
        if (line.empty() || line[0] == '#') continue;
        std::istringstream fields(line);
        std::string crc_text, rel;
        std::uintmax_t size = 0;
        fields >> crc_text >> size;
        std::getline(fields >> std::ws, rel);
        char* end = nullptr;
        const unsigned long crc = std::strtoul(crc_text.c_str(), &end, 16);
        if (!fields.eof() || rel.empty() || crc_text.size() != 8 || *end != '\0' ||
            rel.find("..") != std::string::npos) {
            throw DatabaseError(path.string() + ":" + std::to_string(number) +
                                ": malformed manifest line");
        }
        const fs::path file = fs::path(dir) / rel;
        if (!fs::is_regular_file(file)) {
            throw DatabaseError(file.string() + ": missing (listed in " + path.string() + ":" +
                                std::to_string(number) + ")");
        }
        const Digest d = digestOf(file, rel);
        if (d.size != size || d.crc != crc) {
            char got[16];
            std::snprintf(got, sizeof(got), "%08lx", static_cast<unsigned long>(d.crc));
            throw DatabaseError(file.string() + ": damaged (" + std::to_string(d.size) +
                                " bytes, CRC-32 " + got + "; " + kManifest + " says " +
                                std::to_string(size) + " bytes, " + crc_text + ")");
        }
    }
    return true;
}

void verifyHeatMaps(const std::string& db_dir, const std::string& heatmaps_dir) {
    if (heatmaps_dir.empty()) return;
    const fs::path rel(heatmaps_dir);
    const std::string where = (fs::path(db_dir) / kDbIni).string() + " [heatmaps] directory: ";
    if (rel.is_absolute() || heatmaps_dir.find("..") != std::string::npos) {
        throw DatabaseError(where + "'" + heatmaps_dir + "' is not a folder inside the database");
    }
    const fs::path dir = fs::path(db_dir) / rel;
    if (!fs::is_directory(dir)) throw DatabaseError(where + dir.string() + " is missing");
    verifyManifest(dir.string());
}

}  // namespace lookup::database
