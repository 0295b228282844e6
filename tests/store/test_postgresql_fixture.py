"""The PostgreSQL server of the tests really runs: a table made, a row written and read back through SQLAlchemy.

Where no server can start the test skips, saying why; CI installs Debian's postgresql (.ci/run), so there it runs.
"""

import pg_server
import sqlalchemy as sa


def test_a_fresh_database_takes_a_row_and_gives_it_back(postgresql_url):
    assert postgresql_url.startswith("postgresql://")
    engine = sa.create_engine(pg_server.sqlalchemy_url(postgresql_url))
    try:
        table = sa.Table("smoke", sa.MetaData(), sa.Column("run_id", sa.String, primary_key=True),
                         sa.Column("samples", sa.Integer))
        with engine.begin() as conn:
            assert not sa.inspect(conn).get_table_names()  # fresh: nothing from another test
            table.create(conn)
            conn.execute(table.insert(), [{"run_id": "run-1", "samples": 86_400_000}])
        with engine.connect() as conn:
            assert conn.execute(sa.select(table)).all() == [("run-1", 86_400_000)]
            assert conn.execute(sa.text("select version()")).scalar().startswith("PostgreSQL")
    finally:
        engine.dispose()
