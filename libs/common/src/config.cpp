#include "lookup/common/config.h"

#include <mrpt/config/CConfigFile.h>

#include <map>
#include <optional>
#include <type_traits>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/common/errors.h"
#include "lookup/common/share_dirs.h"

namespace lookup::common {
namespace {

std::string trim(const std::string& s) {
    const auto begin = s.find_first_not_of(" \t\r\n");
    if (begin == std::string::npos) return {};
    const auto end = s.find_last_not_of(" \t\r\n");
    return s.substr(begin, end - begin + 1);
}

bool startsWith(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// Why `line` (trimmed, not empty) is not a line of an MRPT .ini, or "" when it is one.
std::string iniLineProblem(const std::string& line, bool& in_section) {
    if (line[0] == ';' || line[0] == '#' || startsWith(line, "//") || line[0] == '@') return "";
    if (line[0] == '[') {
        if (line.back() != ']' || line.size() < 3) return "malformed [section] header";
        in_section = true;
        return "";
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos || trim(line.substr(0, eq)).empty()) {
        return "not a 'key = value' line";
    }
    if (!in_section) return "key before the first [section]";
    return "";
}

}  // namespace

template <class T>
std::string rangeText(T min, T max) {
    std::ostringstream o;
    o.precision(12);
    const bool low = min == std::numeric_limits<T>::lowest();
    const bool high = max == std::numeric_limits<T>::max();
    if (low && !high) {
        o << "(-inf, ";
    } else if (std::is_floating_point_v<T> && min == T(kPositive)) {
        o << "(0, ";
    } else {
        o << "[" << min << ", ";
    }
    if (high && !low) {
        o << "inf)";
    } else {
        o << max << "]";
    }
    return o.str();
}
template std::string rangeText(double, double);
template std::string rangeText(int, int);
template std::string rangeText(std::uint64_t, std::uint64_t);

namespace {

// One file read strictly (what loadIniFile promises), its [ini] base not followed.
std::unique_ptr<NamedConfigFile> readIniFile(const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) throw ConfigError(path + ": no such .ini file");
    std::ifstream file(path, std::ios::binary);
    std::stringstream buffer;
    buffer << file.rdbuf();
    if (!file && !file.eof()) throw ConfigError(path + ": cannot read");
    const std::string text = buffer.str();
    if (text.find('\0') != std::string::npos) {
        throw ConfigError(path + ": binary data (NUL bytes), not an .ini file");
    }
    std::stringstream lines(text);
    bool in_section = false;
    std::size_t number = 0;
    for (std::string line; std::getline(lines, line);) {
        ++number;
        line = trim(line);
        if (line.empty()) continue;
        const std::string problem = iniLineProblem(line, in_section);
        if (!problem.empty()) {
            throw ConfigError(path + ":" + std::to_string(number) + ": " + problem + ": '" +
                              line.substr(0, 60) + "'");
        }
    }
    if (!in_section) throw ConfigError(path + ": no [section] (not an .ini file?)");
    return std::make_unique<NamedConfigFile>(text, path);
}

constexpr const char* kIniSection = "ini";

// The file `[ini] base` of `including` names: as given when absolute, else beside `including`
// (unless that is `including` itself: a per-mine file installed as /etc/lookup/localize.ini),
// else in the share folders (a per-mine file copied elsewhere still finds its shipped base).
std::string resolveBase(const std::string& base, const std::string& including) {
    namespace fs = std::filesystem;
    const fs::path given(base);
    if (given.is_absolute()) return base;
    const fs::path beside = fs::path(including).parent_path() / given;
    if (fs::is_regular_file(beside) && !fs::equivalent(beside, including)) return beside.string();
    const std::string shared = findShareFile(base);
    return shared.empty() ? beside.string() : shared;
}

// Every key of `from` but the [ini] section's, written into `into` (a key in both takes
// `from`'s value).
void overlay(const mrpt::config::CConfigFileBase& from, mrpt::config::CConfigFileBase& into) {
    std::vector<std::string> sections;
    from.getAllSections(sections);
    for (const auto& section : sections) {
        if (section == kIniSection) continue;
        std::vector<std::string> keys;
        from.getAllKeys(section, keys);
        for (const auto& key : keys) into.write(section, key, from.read_string(section, key, ""));
    }
}

std::unique_ptr<NamedConfigFile> loadLayered(const std::string& path,
                                             std::vector<std::string>& chain) {
    auto file = readIniFile(path);
    const IniSection ini(*file, kIniSection, path);
    if (!ini.exists()) return file;
    ini.rejectUnknownKeys({"base"});
    const std::string base_path = resolveBase(ini.requireString("base"), path);
    chain.push_back(std::filesystem::weakly_canonical(path).string());
    if (std::find(chain.begin(), chain.end(),
                  std::filesystem::weakly_canonical(base_path).string()) != chain.end()) {
        throw ConfigError(ini.where("base") + base_path + " is already in this file's chain of " +
                          "bases (a cycle)");
    }
    std::unique_ptr<NamedConfigFile> base;
    try {
        base = loadLayered(base_path, chain);
    } catch (const ConfigError& e) {
        throw ConfigError(ini.where("base") + e.what());
    }
    auto merged = std::make_unique<NamedConfigFile>();
    overlay(*base, *merged);
    overlay(*file, *merged);
    merged->setFileName(path + " (over " + base->fileName() + ")");
    return merged;
}

}  // namespace

std::unique_ptr<NamedConfigFile> loadIniFile(const std::string& path) {
    std::vector<std::string> chain;
    return loadLayered(path, chain);
}

std::string configSourceName(const mrpt::config::CConfigFileBase& config) {
    if (const auto* named = dynamic_cast<const NamedConfigFile*>(&config)) {
        return named->fileName();
    }
    if (const auto* file = dynamic_cast<const mrpt::config::CConfigFile*>(&config)) {
        return file->getAssociatedFile();
    }
    return "<memory>";
}

IniSection::IniSection(const mrpt::config::CConfigFileBase& config, std::string section,
                       std::string source_name)
    : config_(config), section_(std::move(section)), source_name_(std::move(source_name)) {}

IniSection::IniSection(const mrpt::config::CConfigFileBase& config, std::string section)
    : IniSection(config, std::move(section), configSourceName(config)) {}

bool IniSection::exists() const { return config_.sectionExists(section_); }

bool IniSection::has(const std::string& key) const { return !raw(key).empty(); }

std::string IniSection::where(const std::string& key) const {
    return source_name_ + " [" + section_ + "] " + key + ": ";
}

std::string IniSection::raw(const std::string& key) const {
    // MRPT strips trailing comments ("// ..." and "# ...") from values.
    return trim(config_.read_string(section_, key, "", false));
}

double IniSection::getDouble(const std::string& key, double fallback, double min,
                             double max) const {
    const std::string text = raw(key);
    if (text.empty()) return fallback;
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0') {
        throw ConfigError(where(key) + "'" + text + "' is not a number");
    }
    if (!std::isfinite(value)) throw ConfigError(where(key) + "'" + text + "' is not finite");
    if (value < min || value > max) {
        throw ConfigError(where(key) + text + " is out of range " + rangeText(min, max));
    }
    return value;
}

int IniSection::getInt(const std::string& key, int fallback, int min, int max) const {
    const std::string text = raw(key);
    if (text.empty()) return fallback;
    char* end = nullptr;
    errno = 0;
    const long long value = std::strtoll(text.c_str(), &end, 10);
    if (end == text.c_str() || *end != '\0') {
        throw ConfigError(where(key) + "'" + text + "' is not an integer");
    }
    if (errno == ERANGE || value < min || value > max) {
        throw ConfigError(where(key) + text + " is out of range " + rangeText(min, max));
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

void IniSection::validate(const std::function<void()>& check) const {
    try {
        check();
    } catch (const ConfigError& e) {
        throw ConfigError(source_name_ + " [" + section_ + "]: " + e.what());
    }
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

namespace {

bool isNumber(const std::string& text) {
    if (text.empty()) return false;
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    return end != text.c_str() && *end == '\0' && std::isfinite(v);
}

bool isBoolWord(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    return text == "true" || text == "false" || text == "yes" || text == "no" || text == "on" ||
           text == "off";
}

bool isBool(const std::string& text) { return isBoolWord(text) || text == "0" || text == "1"; }

std::string lowerCase(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
    return s;
}

// A view of `config` that records every key an MRPT loader asks for, with the default the
// loader passes (its text tells the value's kind: a number, a 0/1 boolean, an enum name).
class KeyRecorder : public mrpt::config::CConfigFileBase {
  public:
    explicit KeyRecorder(const mrpt::config::CConfigFileBase& config) : config_(config) {}
    mutable std::map<std::string, std::string> defaults;  ///< "section/key" (lower case) -> default

    void getAllSections(std::vector<std::string>& sections) const override {
        config_.getAllSections(sections);
    }
    void getAllKeys(const std::string& section, std::vector<std::string>& keys) const override {
        config_.getAllKeys(section, keys);
    }
    void clear() override {}

  protected:
    void writeString(const std::string&, const std::string&, const std::string&) override {}
    std::string readString(const std::string& section, const std::string& name,
                           const std::string& default_text, bool required) const override {
        defaults[lowerCase(section) + "/" + lowerCase(name)] = default_text;
        return config_.read_string(section, name, default_text, required);
    }

  private:
    const mrpt::config::CConfigFileBase& config_;
};

// The numbers of a "[1 2 3]" vector text, or nullopt when it is not one.
std::optional<std::size_t> vectorSize(const std::string& text) {
    if (text.size() < 2 || text.front() != '[' || text.back() != ']') return std::nullopt;
    std::stringstream in(text.substr(1, text.size() - 2));
    std::size_t n = 0;
    for (std::string item; in >> item; ++n) {
        if (!isNumber(item)) return std::nullopt;
    }
    return n;
}

}  // namespace

void checkMrptSection(const mrpt::config::CConfigFileBase& config, const std::string& section,
                      const std::function<void(const mrpt::config::CConfigFileBase&)>& load,
                      const std::vector<std::string>& extra) {
    if (!config.sectionExists(section)) return;
    KeyRecorder recorder(config);
    std::string load_error;  // reported after the key checks, which name the key
    try {
        load(recorder);
    } catch (const std::exception& e) {
        load_error = configSourceName(config) + " [" + section + "]: " + errorLine(e);
    }
    const IniSection user(config, section);
    std::vector<std::string> keys;
    config.getAllKeys(section, keys);
    for (const auto& key : keys) {
        const std::string value = user.getString(key, "");
        const auto it = recorder.defaults.find(lowerCase(section) + "/" + lowerCase(key));
        if (it == recorder.defaults.end() && !load_error.empty()) continue;  // not reached
        if (it == recorder.defaults.end()) {
            if (std::find(extra.begin(), extra.end(), lowerCase(key)) != extra.end()) continue;
            throw ConfigError(user.where(key) + "unknown key (MRPT does not read it)");
        }
        const std::string& dflt = it->second;
        if (isBoolWord(dflt) && !isBool(value)) {
            throw ConfigError(user.where(key) + "'" + value + "' is not a boolean");
        }
        if (isNumber(dflt) && !isNumber(value) && !(isBool(dflt) && isBool(value))) {
            throw ConfigError(user.where(key) + "'" + value + "' is not a finite number");
        }
        const bool bracketed = value.size() >= 2 && value.front() == '[' && value.back() == ']';
        if (bracketed && !vectorSize(value)) {
            throw ConfigError(user.where(key) + "'" + value +
                              "' is not a vector of finite numbers");
        }
        if (const auto n = vectorSize(dflt); n && vectorSize(value) != n) {
            throw ConfigError(user.where(key) + "'" + value + "' is not a vector of " +
                              std::to_string(*n) + " finite numbers");
        }
    }
    if (!load_error.empty()) throw ConfigError(load_error);
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
