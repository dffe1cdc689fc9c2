"""The portal's own tests: Django in the test process on a data folder of its own (devtools.service),
set up when these tests are collected (their modules import the models)."""
import pytest


def pytest_configure(config):
    from devtools.service import django_for_tests
    django_for_tests()


@pytest.fixture(scope="session")
def portal():
    """The test data folder."""
    from django.conf import settings
    return settings.DATA_DIR
