std = "min"
include_files = { "src/**/*.lua", "spec/**/*.lua", "examples/**/*.lua", "bench/**/*.lua", "bin/*",
  "rockspec/*.rockspec", ".luacheckrc", ".busted" }
files["spec"] = { std = "+busted" }
files["rockspec"] = { globals = { "rockspec_format", "package", "version", "source",
  "description", "dependencies", "test_dependencies", "build", "test", "build_dependencies" } }
files[".luacheckrc"] = { globals = { "std", "include_files", "exclude_files", "files",
  "max_line_length", "ignore" } }
max_line_length = 100
-- the data sets' camera files are data, written by their generators
exclude_files = { "bench/dev/**", "bench/realdata/**" }
-- `not (x > 0)` is deliberate throughout: unlike `x <= 0` it is also true for NaN
ignore = { "581" }
