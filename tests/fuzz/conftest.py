def pytest_configure(config):
    config.addinivalue_line(
        "markers", "fuzz: the seeded mutation fuzzer of the file readers (tests/fuzz; REPRO_FUZZ_N scales it)"
    )
