#pragma once
// One table of (key, field) per .ini section drives loading, saving and the unknown-key check,
// so the three cannot disagree and each key is written once. An options struct derives from
// TableOptions and lists its keys once:
//
//   struct MatcherOptions : common::TableOptions<MatcherOptions> {
//       int search_range_px = 40;
//       void declareKeys(common::OptionsTable& t) {
//           t.add("search_range_px", search_range_px, 2, 512);  // range checked at load
//       }
//       void check() const;  // cross-field validation, run by the consumer's constructor
//   };
//
// Loading only reads and range-checks keys; apps run check() through loadAndCheck so its errors
// name the file too.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/config/CLoadableOptions.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lookup/common/config.h"

namespace lookup::common {

/// The {name, value} pairs of an enum as the .ini spells them, in the order errors list them.
template <class E>
using EnumNames = std::vector<std::pair<std::string, E>>;

/// The name of `value` in `names` ("" when it has none).
template <class E>
std::string enumName(const EnumNames<E>& names, E value) {
    for (const auto& [name, v] : names) {
        if (v == value) return name;
    }
    return {};
}

/// The value named `name` in `names` (nullopt when none is).
template <class E>
std::optional<E> enumValue(const EnumNames<E>& names, const std::string& name) {
    for (const auto& [n, v] : names) {
        if (n == name) return v;
    }
    return std::nullopt;
}

class OptionsTable {
  public:
    /// Numbers: a value outside [min, max] is refused at load, naming the range, and by
    /// checkRanges (values set in code).
    OptionsTable& add(const std::string& key, double& v,
                      double min = std::numeric_limits<double>::lowest(),
                      double max = std::numeric_limits<double>::max());
    OptionsTable& add(const std::string& key, int& v, int min = std::numeric_limits<int>::min(),
                      int max = std::numeric_limits<int>::max());
    OptionsTable& add(const std::string& key, std::uint64_t& v, std::uint64_t min = 0,
                      std::uint64_t max = std::numeric_limits<std::uint64_t>::max());
    /// true/false/yes/no/on/off/1/0; saved as true or false.
    OptionsTable& add(const std::string& key, bool& v);
    /// An empty value keeps the current one.
    OptionsTable& add(const std::string& key, std::string& v);
    /// An enum: a name not in `names` is refused with the list of allowed names.
    template <class E>
    OptionsTable& add(const std::string& key, E& v, const EnumNames<E>& names) {
        std::vector<std::string> list;
        for (const auto& [name, value] : names) list.push_back(name);
        return addChoice(
            key, std::move(list),
            [&v, names]() {
                for (std::size_t i = 0; i < names.size(); ++i) {
                    if (names[i].second == v) return i;
                }
                return std::size_t{0};
            },
            [&v, names](std::size_t i) { v = names[i].second; });
    }

    /// The last key added is saved only while `save_if` holds (a key a file without the
    /// feature never had, so its saved text stays as it was).
    void saveOnlyIf(std::function<bool()> save_if);

    /// Refuses a key of the section that is not in the table ("FILE [SECTION] KEY: unknown
    /// key"), then reads every key present; absent keys keep their values.
    void load(const IniSection& section) const;
    void load(const mrpt::config::CConfigFileBase& source, const std::string& section) const;
    /// Writes every key, in table order, in a form load() reads back to the same value.
    void save(mrpt::config::CConfigFileBase& target, const std::string& section) const;
    /// Adds to `c` every number outside the range its entry was given ("KEY must be in
    /// [min, max]"), so a struct's check() need not repeat the ranges.
    void checkRanges(OptionsCheck& c) const;

    std::vector<std::string> keys() const;

  private:
    OptionsTable& addChoice(const std::string& key, std::vector<std::string> names,
                            std::function<std::size_t()> get, std::function<void(std::size_t)> set);
    struct Entry {
        std::string key;
        std::function<void(const IniSection&)> load;
        std::function<std::string()> text;
        std::function<bool()> save_if;
        std::function<void(OptionsCheck&)> check;
    };
    OptionsTable& addEntry(std::string key, std::function<void(const IniSection&)> load,
                           std::function<std::string()> text,
                           std::function<void(OptionsCheck&)> check = {});
    std::vector<Entry> entries_;
};

/// An MRPT CLoadableOptions whose load and save are its table: `Derived` has
/// `void declareKeys(OptionsTable&)` adding every key (in the order files list them).
template <class Derived>
class TableOptions : public mrpt::config::CLoadableOptions {
  public:
    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override {
        OptionsTable t;
        static_cast<Derived&>(*this).declareKeys(t);
        t.load(source, section);
    }
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override {
        Derived copy = static_cast<const Derived&>(*this);  // the table binds mutable fields
        OptionsTable t;
        copy.declareKeys(t);
        t.save(target, section);
    }

  protected:
    /// The table's ranges, for check(): see OptionsTable::checkRanges.
    void checkRanges(OptionsCheck& c) const {
        Derived copy = static_cast<const Derived&>(*this);
        OptionsTable t;
        copy.declareKeys(t);
        t.checkRanges(c);
    }
};

/// Loads `options` from `section` of `source` and runs its check(), so a bad key and a bad
/// combination of values both come back as "FILE [SECTION] ...". For options spread over
/// several sections (`RefinerOptions`), `section` is their prefix.
template <class T>
void loadAndCheck(T& options, const mrpt::config::CConfigFileBase& source,
                  const std::string& section) {
    options.loadFromConfigFile(source, section);
    IniSection(source, section).validate([&options] { options.check(); });
}

/// Refuses a section of `source` that is not in `known`: "FILE [SECTION]: unknown section
/// (known: ...)". A known name ending in '*' stands for every section starting with the rest.
void rejectUnknownSections(const mrpt::config::CConfigFileBase& source,
                           const std::vector<std::string>& known);

}  // namespace lookup::common
