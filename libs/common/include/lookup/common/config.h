#pragma once
// Strict reading of MRPT-style .ini sections: every error names the file, section and key,
// and values that do not parse completely are refused instead of silently read as 0.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace lookup::common {

/// As the minimum of a range: the value must be > 0 (messages say "(0, ...").
constexpr double kPositive = std::numeric_limits<double>::min();

/// A configuration value that is missing, malformed or out of range.
class ConfigError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// An .ini text in memory that remembers the file it came from (for error messages).
class NamedConfigFile : public mrpt::config::CConfigFileMemory {
  public:
    NamedConfigFile() = default;
    NamedConfigFile(const std::string& text, std::string file_name)
        : mrpt::config::CConfigFileMemory(text), file_name_(std::move(file_name)) {}
    const std::string& fileName() const { return file_name_; }
    void setFileName(std::string name) { file_name_ = std::move(name); }

  private:
    std::string file_name_;
};

/// "[min, max]" as messages write a range: "[0, inf)" when unbounded above, "(0, max]" from
/// kPositive (instantiated for double, int, uint64_t).
template <class T>
std::string rangeText(T min, T max);

/// Reads an .ini file strictly: ConfigError naming the file (and line) when it is missing,
/// unreadable, binary (NUL bytes), has no [section], or holds a line that is neither a comment
/// (`;`, `#`, `//`), a `[section]`, a `key = value` nor an MRPT `@directive`.
/// A file with `[ini] base = FILE` is laid over FILE (itself read this way): every section of
/// both, a key in both takes this file's value, so a variant keeps only what differs. FILE is
/// absolute, beside this file, or in the share folders; a missing base, a cycle or another key
/// in [ini] is a ConfigError naming this file. The result is named "PATH (over BASE)".
std::unique_ptr<NamedConfigFile> loadIniFile(const std::string& path);

/// The file a configuration source was read from (CConfigFile, NamedConfigFile), else
/// "<memory>".
std::string configSourceName(const mrpt::config::CConfigFileBase& config);

/// One section of a configuration source. `source_name` is what errors call the source
/// (normally the file path).
class IniSection {
  public:
    IniSection(const mrpt::config::CConfigFileBase& config, std::string section,
               std::string source_name);
    /// Source named by configSourceName(config).
    IniSection(const mrpt::config::CConfigFileBase& config, std::string section);

    bool exists() const;
    bool has(const std::string& key) const;
    const std::string& section() const { return section_; }
    const std::string& sourceName() const { return source_name_; }

    /// Optional values: `fallback` when the key is absent; ConfigError when present but
    /// malformed, non-finite (nan, inf) or outside [min, max] (the message names the range).
    double getDouble(const std::string& key, double fallback,
                     double min = std::numeric_limits<double>::lowest(),
                     double max = std::numeric_limits<double>::max()) const;
    int getInt(const std::string& key, int fallback, int min = std::numeric_limits<int>::min(),
               int max = std::numeric_limits<int>::max()) const;
    bool getBool(const std::string& key, bool fallback) const;
    std::string getString(const std::string& key, const std::string& fallback) const;

    /// Required values: ConfigError when absent or malformed.
    double requireDouble(const std::string& key) const;
    int requireInt(const std::string& key) const;
    std::string requireString(const std::string& key) const;

    /// Refuses keys that are not in `known` (catches typos such as `sped_kmh`).
    void rejectUnknownKeys(const std::vector<std::string>& known) const;

    /// Runs an options validator (e.g. `[&] { check(); }`) and prefixes its ConfigError with
    /// "FILE [SECTION]: ", so field errors found after loading still name the file.
    void validate(const std::function<void()>& check) const;

    /// "FILE [SECTION] KEY: " prefix used in every message about this section.
    std::string where(const std::string& key) const;

  private:
    std::string raw(const std::string& key) const;

    const mrpt::config::CConfigFileBase& config_;
    std::string section_;
    std::string source_name_;
};

/// Checks a section that an MRPT loader reads itself (MRPT ignores unknown keys and reads
/// malformed numbers as 0): `load(view)` runs the loader on a view of `config` that records the
/// keys it reads and their defaults. Throws ConfigError naming the file, section and key for a
/// key the loader does not read (unless in `extra_keys`, lower case) and for a value that is
/// not a finite number, a boolean or a vector of numbers where the default is one; an error of
/// the loader itself is returned as a ConfigError naming the file and section.
void checkMrptSection(const mrpt::config::CConfigFileBase& config, const std::string& section,
                      const std::function<void(const mrpt::config::CConfigFileBase&)>& load,
                      const std::vector<std::string>& extra_keys = {});

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
