//! `stereoshim top`'s edits of the config file: one key of an app's section (`[app."NAME"]`) set
//! to a value, everything else — comments, order, spacing, other sections — left as the person
//! wrote it (toml_edit keeps the document's formatting). A new key is written as a dotted key
//! (`mask.enabled = true`) in the app's section, as docs/configuration.md writes them; a section
//! the file lacks is added at its end. Pure over text: `top` reads the file, edits, and writes it
//! back atomically.
#![forbid(unsafe_code)]

use toml_edit::{DocumentMut, Item, Table, Value};

/// A config value as `top` writes it.
#[derive(Clone, Debug, PartialEq)]
pub enum Setting {
    Bool(bool),
    Text(String),
    Float(f64),
}

impl Setting {
    fn value(&self) -> Value {
        match self {
            Setting::Bool(b) => Value::from(*b),
            Setting::Text(t) => Value::from(t.as_str()),
            Setting::Float(f) => Value::from(*f),
        }
    }

    /// As a TOML value in a plain `key = value` line (`top`'s live settings file).
    pub fn toml(&self) -> String {
        self.value().to_string().trim().to_string()
    }
}

/// `text` with `key` (dotted, e.g. `foveation.preset`) of app `app`'s section set to `value`.
/// Fails on a file that is not TOML (the person's file is then left alone), or where the path is
/// taken by something that is not a table (e.g. `app = 1`).
pub fn set(text: &str, app: &str, key: &str, value: &Setting) -> Result<String, String> {
    let mut doc: DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| format!("not valid TOML, left as it is: {}", e.message()))?;
    let apps = doc.entry("app").or_insert_with(|| {
        // `[app."NAME"]` headers only: no `[app]` header of its own.
        let mut t = Table::new();
        t.set_implicit(true);
        Item::Table(t)
    });
    let apps = apps.as_table_mut().ok_or("`app` is not a table")?;
    let section = apps.entry(app).or_insert_with(|| Item::Table(Table::new())).as_table_mut().ok_or_else(|| format!("app.\"{app}\" is not a table"))?;
    let parts: Vec<&str> = key.split('.').collect();
    let (last, path) = parts.split_last().ok_or("an empty key")?;
    let mut table: &mut dyn toml_edit::TableLike = section;
    for part in path {
        let next = table.entry(part).or_insert({
            // Written `mask.enabled = …` inside the section, not as a `[app."NAME".mask]` table.
            let mut t = Table::new();
            t.set_dotted(true);
            Item::Table(t)
        });
        table = match next {
            Item::Table(t) => t,
            Item::Value(Value::InlineTable(t)) => t,
            _ => return Err(format!("app.\"{app}\".{part} is not a table")),
        };
    }
    match table.get_mut(last) {
        // Keep the line's own decoration (a trailing comment) when replacing a value.
        Some(Item::Value(v)) => {
            let decor = v.decor().clone();
            *v = value.value();
            *v.decor_mut() = decor;
        }
        _ => {
            table.insert(last, Item::Value(value.value()));
        }
    }
    Ok(doc.to_string())
}

/// The value of `key` in app `app`'s section, if the file sets it there.
pub fn get(text: &str, app: &str, key: &str) -> Option<Setting> {
    let doc: DocumentMut = text.parse().ok()?;
    let mut item = doc.get("app")?.get(app)?;
    for part in key.split('.') {
        item = item.get(part)?;
    }
    let v = item.as_value()?;
    v.as_bool().map(Setting::Bool).or_else(|| v.as_str().map(|s| Setting::Text(s.to_string()))).or_else(|| v.as_float().or(v.as_integer().map(|i| i as f64)).map(Setting::Float))
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "# my stereoshim settings\nlog.level = \"info\"   # keep the log short\n\n[app.\"My VR Game\"]\n# the lens mask pays here\nmask.enabled = true  # measured 1.3x\nfoveation.preset = \"subtle\"\n\n[app.\"Other\"]\nenabled = false\n";

    #[test]
    fn a_key_is_replaced_in_place_with_its_comment() {
        let out = set(FILE, "My VR Game", "mask.enabled", &Setting::Bool(false)).unwrap();
        assert_eq!(out, FILE.replace("mask.enabled = true  # measured 1.3x", "mask.enabled = false  # measured 1.3x"));
        assert_eq!(get(&out, "My VR Game", "mask.enabled"), Some(Setting::Bool(false)));
    }

    #[test]
    fn a_new_key_goes_into_the_section_as_a_dotted_key() {
        let out = set(FILE, "My VR Game", "far_field.enabled", &Setting::Bool(true)).unwrap();
        assert!(out.starts_with("# my stereoshim settings\nlog.level = \"info\"   # keep the log short\n"), "{out}");
        assert!(out.contains("far_field.enabled = true\n"), "{out}");
        assert!(!out.contains("[app.\"My VR Game\".far_field]"), "{out}");
        assert!(out.contains("[app.\"Other\"]\nenabled = false\n"), "{out}");
        // Under the right section, before the next.
        let (mine, other) = out.split_once("[app.\"Other\"]").unwrap();
        assert!(mine.contains("far_field.enabled") && !other.contains("far_field"), "{out}");
        let out = set(&out, "My VR Game", "foveation.preset", &Setting::Text("aggressive".into())).unwrap();
        assert_eq!(get(&out, "My VR Game", "foveation.preset"), Some(Setting::Text("aggressive".into())));
        assert_eq!(get(&out, "My VR Game", "upscale.scale"), None);
    }

    #[test]
    fn a_new_section_and_an_empty_file() {
        let out = set(FILE, "New App", "upscale.scale", &Setting::Float(0.75)).unwrap();
        assert!(out.starts_with(FILE), "{out}");
        assert!(out.ends_with("[app.\"New App\"]\nupscale.scale = 0.75\n"), "{out}");
        let out = set("", "xr-scene", "mask.enabled", &Setting::Bool(true)).unwrap();
        assert_eq!(out, "[app.xr-scene]\nmask.enabled = true\n");
    }

    #[test]
    fn what_the_layer_reads_back() {
        let out = set(FILE, "My VR Game", "foveation.enabled", &Setting::Bool(true)).unwrap();
        let keys = crate::registry::keys();
        let (c, d) = crate::core::config::Config::resolve(&crate::core::config::Inputs { keys, file: Some((std::path::Path::new("/c.toml"), &out)), app_names: &["My VR Game"], env: &|_| None });
        assert!(d.is_empty(), "{d:?}");
        assert!(c.bool("foveation.enabled") && c.bool("mask.enabled"));
        assert_eq!(c.choice("foveation.preset"), "subtle");
    }

    #[test]
    fn bad_files_are_left_alone() {
        assert!(set("mask.enabled = \n", "a", "mask.enabled", &Setting::Bool(true)).unwrap_err().contains("not valid TOML"));
        assert!(set("app = 1\n", "a", "mask.enabled", &Setting::Bool(true)).unwrap_err().contains("not a table"));
        assert_eq!(Setting::Text("rdm".into()).toml(), "\"rdm\"");
        assert_eq!(Setting::Bool(true).toml(), "true");
    }
}
