"""Tests of uqdrape.files: the TOML reader's one-line errors, Table's checks, the atomic writers."""

from pathlib import Path

import pytest

from uqdrape.files import (MAX_TOML_BYTES, MAX_TOML_DEPTH, Document, FileFormatError, Table, read_toml,
                           write_all, write_atomic, write_text_atomic)


def one_line_naming(err, path):
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"{path}: ")
    assert err.value.path == Path(path)
    return text


@pytest.mark.parametrize("text", [
    "a = " + "[" * 3000 + "]" * 3000,
    "a = " + "{ b = " * 3000 + "1" + " }" * 3000,
    "a = " + "[" * (MAX_TOML_DEPTH + 1) + "]" * (MAX_TOML_DEPTH + 1),  # parses, but deeper than allowed
    "[" + ".".join(["t"] * (MAX_TOML_DEPTH + 1)) + "]\n",
])
def test_deep_nesting_is_one_line_naming_the_file_and_the_limit(tmp_path, text):
    path = tmp_path / "deep.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FileFormatError) as err:
        read_toml(path, "study file")
    assert f"nested more than {MAX_TOML_DEPTH} levels deep" in one_line_naming(err, path)


def test_nesting_at_the_limit_is_read(tmp_path):
    path = tmp_path / "ok.toml"
    depth = MAX_TOML_DEPTH - 1  # the top-level table is one level
    path.write_text("a = " + "[" * depth + "1" + "]" * depth, encoding="utf-8")
    value = read_toml(path, "study file")["a"]
    for _ in range(depth):
        value = value[0]
    assert value == 1


@pytest.mark.parametrize("encoding", ["utf-16", "utf-8-sig", "utf-8"])
def test_utf16_and_utf8_with_or_without_a_mark_are_read(tmp_path, encoding):
    path = tmp_path / "t.toml"
    path.write_text('name = "Naïve φ"\nn = 3\n', encoding=encoding)
    assert read_toml(path, "card") == {"name": "Naïve φ", "n": 3}


def test_binary_file_names_the_first_bad_byte_and_echoes_nothing(tmp_path):
    path = tmp_path / "img.toml"
    secret = b"name = 'secret-words'\n"
    path.write_bytes(secret + b"\x89PNG\r\n")
    with pytest.raises(FileFormatError) as err:
        read_toml(path, "material card")
    text = one_line_naming(err, path)
    assert f"byte 0x89 at offset {len(secret)}" in text and "save the material card as UTF-8" in text
    assert "secret" not in text


def test_invalid_toml_gives_tomllib_position_not_contents(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('a = 1\nsecret = = "hidden"\n', encoding="utf-8")
    with pytest.raises(FileFormatError) as err:
        read_toml(path, "study file")
    text = one_line_naming(err, path)
    assert "not valid TOML" in text and "line 2" in text and "hidden" not in text


def test_missing_file_and_folder_say_why(tmp_path):
    with pytest.raises(FileFormatError) as err:
        read_toml(tmp_path / "nope.toml", "architecture file")
    assert "cannot read the architecture file: No such file or directory" in one_line_naming(err, tmp_path / "nope.toml")
    with pytest.raises(FileFormatError) as err:
        read_toml(tmp_path, "architecture file")
    assert "is a folder, not a regular file" in one_line_naming(err, tmp_path)


def test_oversize_file_is_refused_before_parsing(tmp_path):
    path = tmp_path / "big.toml"
    path.write_bytes(b"# " + b"x" * MAX_TOML_BYTES + b"\n")
    with pytest.raises(FileFormatError) as err:
        read_toml(path, "study file")
    assert "larger than 10 MB" in one_line_naming(err, path)


def test_error_class_can_be_a_subclass(tmp_path):
    class StudyLikeError(FileFormatError):
        pass

    with pytest.raises(StudyLikeError):
        read_toml(tmp_path / "nope.toml", "study file", error=StudyLikeError)


# ----------------------------------------------------------------------------- Document / Table

def table(tmp_path, data, name="process", keys=None):
    return Table(Document(tmp_path / "s.toml", "study file"), name, data, keys)


@pytest.mark.parametrize("data, call, key, message", [
    ({"friction": 1.5}, lambda t: t.number("friction", ge=0, lt=1), "process.friction",
     "process.friction = 1.5 is invalid: friction must be a number with 0 <= friction < 1"),
    ({"friction": True}, lambda t: t.number("friction"), "process.friction",
     "process.friction = true is invalid: friction must be a finite number"),
    ({"rings": 2.0}, lambda t: t.number("rings", integer=True, ge=1), "process.rings",
     "process.rings = 2.0 is invalid: rings must be an integer >= 1"),
    ({}, lambda t: t.number("rings", integer=True, gt=0), "process.rings",
     "process.rings is missing: rings must be an integer > 0"),
    ({"mode": "fast"}, lambda t: t.string("mode", choices=("energy", "geometric")), "process.mode",
     'process.mode = "fast" is invalid: mode must be one of "energy", "geometric"'),
    ({"lapping": [1, 0.5]}, lambda t: t.numbers("lapping", integer=True, hint="integers"), "process.lapping",
     "process.lapping = [1, 0.5] is invalid: integers"),
    ({"xy": [1, 2, 3]}, lambda t: t.numbers("xy", length=2, hint="two numbers"), "process.xy",
     "process.xy = [1, 2, 3] is invalid: two numbers"),
    ({"frcition": 0.2}, lambda t: t.only(("friction", "sectors")), "process.frcition",
     "unknown key process.frcition; valid keys in [process]: friction, sectors"),
])
def test_table_errors_carry_the_dotted_key(tmp_path, data, call, key, message):
    with pytest.raises(FileFormatError) as err:
        call(table(tmp_path, data))
    assert str(err.value) == f"{tmp_path / 's.toml'}: {message}"
    assert err.value.key == key


def test_top_level_and_sub_tables(tmp_path):
    top = table(tmp_path, {"name": "x", "stitch": {"gauge": 6, "bad": 1}}, name="", keys=("name", "stitch"))
    assert top.string("name") == "x" and top.dotted("name") == "name"
    stitch = top.table("stitch")
    assert stitch.number("gauge", gt=0) == 6.0 and top.table("compaction").data == {}
    with pytest.raises(FileFormatError) as err:
        stitch.only(("gauge",))
    assert err.value.key == "stitch.bad" and "valid keys in [stitch]: gauge" in str(err.value)
    with pytest.raises(FileFormatError) as err:
        top.only(("stitch",))
    assert "unknown key name; valid keys in the file's top level: stitch" in str(err.value)
    with pytest.raises(FileFormatError) as err:
        table(tmp_path, {"stitch": 3}, name="").table("stitch")
    assert err.value.key == "stitch" and "stitch = 3 is invalid: stitch must be a table [stitch]" in str(err.value)


def test_values_read_and_defaults(tmp_path):
    t = table(tmp_path, {"f": 1, "n": 3, "xs": [1, 2.5], "s": "a"})
    assert t.number("f") == 1.0 and isinstance(t.number("f"), float)
    assert t.number("n", integer=True) == 3 and t.number("g", 0.2) == 0.2
    assert t.numbers("xs", hint="") == (1.0, 2.5) and t.string("s") == "a" and t.string("u", "d") == "d"


def test_relative_file(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "c.csv").write_text("x")
    doc = Document(tmp_path / "s.toml", "study file")
    assert doc.relative_file("fabric.material", "sub/c.csv") == tmp_path / "sub" / "c.csv"
    with pytest.raises(FileFormatError) as err:
        doc.relative_file("fabric.material", "sub/d.csv")
    assert err.value.key == "fabric.material" and "file not found" in str(err.value)
    with pytest.raises(FileFormatError, match="must be a file name .relative to the study file."):
        doc.relative_file("fabric.material", 3)


# ----------------------------------------------------------------------------- writing

def test_write_atomic_leaves_nothing_on_failure_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "out" / "a.vtu"

    def half(tmp):
        assert tmp.name == "a.part.vtu"  # beside the target, the suffix kept
        tmp.write_text("half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        write_atomic(target, half)
    assert list((tmp_path / "out").iterdir()) == []
    write_text_atomic(target, "old")

    def interrupted(tmp):
        tmp.write_text("new, half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, interrupted)
    assert target.read_text() == "old" and sorted(p.name for p in target.parent.iterdir()) == ["a.vtu"]


def test_write_atomic_target_appears_only_complete(tmp_path):
    target = tmp_path / "r.nc"

    def write(tmp):
        assert tmp.name == "r.nc.part" and not target.exists()
        tmp.write_text("complete")

    assert write_atomic(target, write, keep_suffix=False) == target
    assert target.read_text() == "complete" and [p.name for p in tmp_path.iterdir()] == ["r.nc"]
    assert write_atomic(tmp_path / "s.nc", lambda tmp: tmp.write_text("x") and False) is None
    assert [p.name for p in tmp_path.iterdir()] == ["r.nc"]
    assert write_text_atomic(tmp_path / "e.txt", "") == tmp_path / "e.txt"  # write_text's 0 is not False


def test_write_all_is_all_or_nothing(tmp_path):
    def bad(tmp):
        raise ValueError("no")

    writers = {tmp_path / "a.csv": lambda tmp: tmp.write_text("a"), tmp_path / "d" / "b.dxf": bad}
    with pytest.raises(ValueError):
        write_all(writers)
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []
    written = write_all({tmp_path / "a.csv": lambda tmp: tmp.write_text("a"),
                         tmp_path / "d" / "b.dxf": lambda tmp: tmp.write_text("b")})
    assert written == [tmp_path / "a.csv", tmp_path / "d" / "b.dxf"]
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["a.csv", "b.dxf"]
