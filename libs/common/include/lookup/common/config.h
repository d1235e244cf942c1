#pragma once
// Strict reading of MRPT-style .ini sections: every error names the file, section and key,
// and values that do not parse completely are refused instead of silently read as 0.

#include <mrpt/config/CConfigFileBase.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace lookup::common {

/// A configuration value that is missing, malformed or out of range.
class ConfigError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// One section of a configuration source. `source_name` is what errors call the source
/// (normally the file path).
class IniSection {
public:
    IniSection(const mrpt::config::CConfigFileBase& config, std::string section,
               std::string source_name);

    bool exists() const;
    bool has(const std::string& key) const;
    const std::string& section() const { return section_; }
    const std::string& sourceName() const { return source_name_; }

    /// Optional values: `fallback` when the key is absent; ConfigError when present but
    /// malformed.
    double getDouble(const std::string& key, double fallback) const;
    int getInt(const std::string& key, int fallback) const;
    bool getBool(const std::string& key, bool fallback) const;
    std::string getString(const std::string& key, const std::string& fallback) const;

    /// Required values: ConfigError when absent or malformed.
    double requireDouble(const std::string& key) const;
    int requireInt(const std::string& key) const;
    std::string requireString(const std::string& key) const;

    /// Refuses keys that are not in `known` (catches typos such as `sped_kmh`).
    void rejectUnknownKeys(const std::vector<std::string>& known) const;

    /// "FILE [SECTION] KEY: " prefix used in every message about this section.
    std::string where(const std::string& key) const;

private:
    std::string raw(const std::string& key) const;

    const mrpt::config::CConfigFileBase& config_;
    std::string section_;
    std::string source_name_;
};

/// Collects option-validation failures so a validator can report every bad field at once.
/// Usage: `OptionsCheck c("refine.matcher"); c.require(x > 0, "search_range_px", "> 0");`
class OptionsCheck {
public:
    explicit OptionsCheck(std::string owner) : owner_(std::move(owner)) {}
    void require(bool condition, const std::string& field, const std::string& expectation);
    bool ok() const { return failures_.empty(); }
    /// All failures, one per line, each prefixed by the owner and field name.
    std::string message() const;
    /// Throws ConfigError(message()) when any check failed.
    void throwIfFailed() const;

private:
    std::string owner_;
    std::vector<std::string> failures_;
};

}  // namespace lookup::common
