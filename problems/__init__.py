"""The problem catalog: one module per problem or per book chapter; references/ holds data."""
