#include "lookup/common/config.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>

namespace lookup::common {
namespace {

std::string trim(const std::string& s) {
    const auto begin = s.find_first_not_of(" \t\r\n");
    if (begin == std::string::npos) return {};
    const auto end = s.find_last_not_of(" \t\r\n");
    return s.substr(begin, end - begin + 1);
}

}  // namespace

IniSection::IniSection(const mrpt::config::CConfigFileBase& config, std::string section,
                       std::string source_name)
    : config_(config), section_(std::move(section)), source_name_(std::move(source_name)) {}

bool IniSection::exists() const { return config_.sectionExists(section_); }

bool IniSection::has(const std::string& key) const { return !raw(key).empty(); }

std::string IniSection::where(const std::string& key) const {
    return source_name_ + " [" + section_ + "] " + key + ": ";
}

std::string IniSection::raw(const std::string& key) const {
    // MRPT strips trailing comments ("// ..." and "# ...") from values.
    return trim(config_.read_string(section_, key, "", false));
}

double IniSection::getDouble(const std::string& key, double fallback) const {
    const std::string text = raw(key);
    if (text.empty()) return fallback;
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0') {
        throw ConfigError(where(key) + "'" + text + "' is not a number");
    }
    return value;
}

int IniSection::getInt(const std::string& key, int fallback) const {
    const std::string text = raw(key);
    if (text.empty()) return fallback;
    char* end = nullptr;
    const long value = std::strtol(text.c_str(), &end, 10);
    if (end == text.c_str() || *end != '\0') {
        throw ConfigError(where(key) + "'" + text + "' is not an integer");
    }
    return static_cast<int>(value);
}

bool IniSection::getBool(const std::string& key, bool fallback) const {
    std::string text = raw(key);
    if (text.empty()) return fallback;
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (text == "1" || text == "true" || text == "yes" || text == "on") return true;
    if (text == "0" || text == "false" || text == "no" || text == "off") return false;
    throw ConfigError(where(key) + "'" + text + "' is not a boolean (true/false/1/0)");
}

std::string IniSection::getString(const std::string& key, const std::string& fallback) const {
    const std::string text = raw(key);
    return text.empty() ? fallback : text;
}

double IniSection::requireDouble(const std::string& key) const {
    if (!has(key)) throw ConfigError(where(key) + "required key is missing");
    return getDouble(key, 0.0);
}

int IniSection::requireInt(const std::string& key) const {
    if (!has(key)) throw ConfigError(where(key) + "required key is missing");
    return getInt(key, 0);
}

std::string IniSection::requireString(const std::string& key) const {
    if (!has(key)) throw ConfigError(where(key) + "required key is missing");
    return raw(key);
}

void IniSection::rejectUnknownKeys(const std::vector<std::string>& known) const {
    std::vector<std::string> keys;
    config_.getAllKeys(section_, keys);
    for (const auto& key : keys) {
        if (std::find(known.begin(), known.end(), key) == known.end()) {
            throw ConfigError(where(key) + "unknown key");
        }
    }
}

void OptionsCheck::require(bool condition, const std::string& field,
                           const std::string& expectation) {
    if (!condition) failures_.push_back(owner_ + "." + field + " must be " + expectation);
}

std::string OptionsCheck::message() const {
    std::string out;
    for (const auto& f : failures_) out += (out.empty() ? "" : "\n") + f;
    return out;
}

void OptionsCheck::throwIfFailed() const {
    if (!ok()) throw ConfigError(message());
}

}  // namespace lookup::common
